"""echo_data.dataset"""
