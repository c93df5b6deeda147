"""Drawing vocabulary shared by the step types and the report: result tables
(:mod:`~rotoruq.render.tables`) and figure primitives (:mod:`~rotoruq.render.figures`). The
reference thesis's printed numbers live with the reference application
(:mod:`rotoruq.reference.tables`), which hands them to the figures as plain data.

It sits below :mod:`rotoruq.steps` (each step type composes its tables and figures from these)
and below :mod:`rotoruq.report` (which assembles pages); it knows no step type.
"""
