"""echo-data: training data for sound-triggered mobile manipulation."""
__version__ = "0.1.0"
