"""echo_data.robot"""
