"""Driving MBDyn from rotoruq: hover-rotor templates, a results extractor and a Dakota-style
driver (``python -m rotoruq.mbdyn.driver``). rotoruq does not depend on MBDyn; see
:func:`find_mbdyn` for how it is located."""

from .case import TEMPLATES, CaseSettings, rigid_equivalent, run_case, template_values
from .extract import RESPONSES, HubLoads, hub_loads, read_rotor_output
from .solver import MBDynError, MBDynNotFoundError, MBDynRun, find_mbdyn, run_mbdyn

__all__ = [
    "TEMPLATES",
    "RESPONSES",
    "CaseSettings",
    "HubLoads",
    "MBDynError",
    "MBDynNotFoundError",
    "MBDynRun",
    "find_mbdyn",
    "hub_loads",
    "read_rotor_output",
    "rigid_equivalent",
    "run_case",
    "run_mbdyn",
    "template_values",
]
