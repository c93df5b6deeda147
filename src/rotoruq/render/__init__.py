"""Drawing vocabulary shared by the step types and the report: result tables
(:mod:`~rotoruq.render.tables`), figure primitives (:mod:`~rotoruq.render.figures`) and the
reference thesis's printed numbers (:mod:`~rotoruq.render.reference`).

It sits below :mod:`rotoruq.steps` (each step type composes its tables and figures from these)
and below :mod:`rotoruq.report` (which assembles pages); it knows no step type.
"""
