"""`from support.torch_module import torch` at a test module's top: torch, or the whole module
skipped with the reason where the test extra leaves torch out (Python >= 3.12, support.optional).
Anywhere else a missing torch raises here and the module fails to collect."""

from __future__ import annotations

import importlib

import pytest

from support.optional import left_out

_reason = left_out("torch")
if _reason is not None:
    pytest.skip(_reason, allow_module_level=True)
torch = importlib.import_module("torch")
