"""Simulation: replay plants, effects and recordings."""
