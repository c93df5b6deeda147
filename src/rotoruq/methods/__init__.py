"""rotoruq.methods."""
