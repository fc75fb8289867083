"""Importers: one module per source format, each returning a KeypointMotion."""
