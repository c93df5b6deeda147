"""The hook through which an application built on rotoruq adds to a report.

The report is generic: it renders every saved step with its type's renderers and opens with a
verdict computed from the run. An application (a study of a publication, a certification
campaign, ...) may add its own findings: a title, a verdict of its own, sections, files and
numbers drawn beside the run's in the figures. It does so through an object that satisfies
:class:`Application`, handed to :func:`rotoruq.report.html.write_report` by its caller (the
CLI hands it the reference study's, :mod:`rotoruq.reference`, when a study file declares
``[study] reference = "thesis"``). The report never imports an application.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

from ..results import StepResult

__all__ = ["Application", "Addition", "ReportData", "Section"]


@dataclass(frozen=True)
class Section:
    """A heading (level 2 to 4, listed in the contents) and the HTML under it."""

    level: int
    title: str
    anchor: str
    html: str = ""


@dataclass(frozen=True, eq=False)
class ReportData:
    """What the report read: study -> step -> result, study -> ``study.json``, and study ->
    parameter -> display label."""

    studies: Mapping[str, Mapping[str, StepResult]]
    infos: Mapping[str, Mapping[str, Any]]
    labels: Mapping[str, Mapping[str, str]]


@dataclass(frozen=True)
class Addition:
    """What an application adds to one report.

    title : the page title (None: the report's own). verdict : HTML on the first screen, after
    the run's own verdict. sections : after the first screen, before the studies.
    study_sections : study -> sections after that study's steps, before its figures.
    files : path relative to the report folder -> text, written beside ``index.html``.
    """

    title: str | None = None
    verdict: str = ""
    sections: tuple[Section, ...] = ()
    study_sections: Mapping[str, tuple[Section, ...]] = field(default_factory=dict)
    files: Mapping[str, str] = field(default_factory=dict)


class Application(Protocol):
    """An application's report hook.

    covers(info) : whether the application speaks for a saved study (its ``study.json``).
    beside(study, info) : for a covered study, the numbers its step renderers draw beside
        the run's, as plain data (it crosses to the figure worker process): see
        :class:`rotoruq.render.figures.FigureContext` ``beside``; None: nothing.
    build(data) : the :class:`Addition` for the studies it covers (``data`` holds only those).
    """

    def covers(self, info: Mapping[str, Any]) -> bool: ...

    def beside(self, study: str, info: Mapping[str, Any]) -> dict[str, Any] | None: ...

    def build(self, data: ReportData) -> Addition: ...
