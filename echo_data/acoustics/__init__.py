"""echo_data.acoustics"""
