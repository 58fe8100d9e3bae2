"""Figures (matplotlib) and the browser viewer (meshcat)."""
