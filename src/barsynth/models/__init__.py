"""Synthesis models: one module each, found by name through :func:`get_model`."""

from .base import Mode, get_model, model_names

__all__ = ["Mode", "get_model", "model_names"]
