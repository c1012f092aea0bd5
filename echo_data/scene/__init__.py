"""echo_data.scene"""
