"""Acquisition: driver interface and registry, device URLs, blocks, ring buffer, recorder."""
