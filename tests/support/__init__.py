"""Helpers the test modules share (plans, synthetic episodes, recipes, paths): test modules import
from here (or use the fixtures in tests/conftest.py), never from one another."""
