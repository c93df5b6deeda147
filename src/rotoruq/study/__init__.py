"""rotoruq.study: study files, the runner and the command line.

Importing it registers the built-in step types (:mod:`rotoruq.study.steptypes`), which also
gives the report the renderers of their results.
"""

from . import steptypes  # noqa: F401  (registers the built-in step types)
