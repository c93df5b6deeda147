"""rotoruq.study."""
