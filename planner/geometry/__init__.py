"""Geometry: tip paths and obstacles."""
