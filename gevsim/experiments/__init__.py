"""Studies (flicker, reconstruction, trade-off) and dataset generation."""
