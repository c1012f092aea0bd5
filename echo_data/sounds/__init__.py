"""echo_data.sounds"""
