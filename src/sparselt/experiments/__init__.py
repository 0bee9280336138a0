"""Experiments: one module per thesis table or figure family (config in, artefacts out)."""
