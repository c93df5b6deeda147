"""rotoruq.report."""
