"""echo_data.skills"""
