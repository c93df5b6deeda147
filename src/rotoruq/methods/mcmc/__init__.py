"""rotoruq.methods.mcmc."""
