"""rotoruq.study: study files, the runner and the command line.

The step types themselves live in :mod:`rotoruq.steps` (one module per type, one registry);
this layer parses study files against their option schemas and runs them in order.
"""
