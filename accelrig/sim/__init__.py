"""Simulated sensors and rigs with known ground truth (served by the sim:// driver)."""
