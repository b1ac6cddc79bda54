"""Procedural binaural audio rendered from a simulated Trace."""
