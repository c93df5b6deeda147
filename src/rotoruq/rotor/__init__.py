"""rotoruq.rotor."""
