"""Geometry: ray casting, the ground grid, alpha shapes, draped footprints."""
