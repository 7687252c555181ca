"""Batch rendering: many settings of one model, deterministic per item (spec 11)."""
