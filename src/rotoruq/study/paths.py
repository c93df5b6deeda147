"""The names and paths a study file gives, checked before a run writes anything.

A study file travels: one from a colleague must not write outside its results folder nor read
files outside its own folder. :func:`check_study_paths` checks, naming the study file's line:

- the study name and every step name name one file (:func:`rotoruq.safety.check_name`);
- ``[study] output`` (unless the command line names the folder), ``[store] path`` (unless the
  command line allows an outside store) and ``[model] workdir`` are relative, without ``..``;
- ``[model] templates`` and ``files``, every ``[data.NAME] file`` and every step's ``points``
  file are relative, without ``..``, and stay inside the study file's folder (symlinks
  resolved);
- with the results folder known, the store and the work directory resolve inside it.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

from ..safety import check_name, check_relative, inside
from .locator import Locator
from .spec import Study

__all__ = ["check_study_paths"]


def check_study_paths(study: Study, out: str | os.PathLike | None = None, *,
                      out_given: bool = False, outside_store: bool = False) -> None:
    """Refuse a study whose names or paths would write outside its results folder or read
    outside its own folder.

    Parameters
    ----------
    study : Study
        A parsed study (:func:`rotoruq.study.schema.load_study`); its text gives the lines.
    out : path-like, optional
        The results folder of this run, when known: the store and the work directory must
        resolve inside it (a symlink on the way counts).
    out_given : bool
        The results folder was named on the command line (``--out``): ``[study] output`` is
        not used, so not checked.
    outside_store : bool
        The command line allows a store outside the results folder (``[store] path`` may be
        absolute or climb out).

    Raises
    ------
    rotoruq.errors.InputFileError
        Naming the study file, the line and the offending name or path.

    Examples
    --------
    >>> from rotoruq.study.schema import parse_study
    >>> text = '''
    ... [study]
    ... name = "s"
    ... output = "../../elsewhere"
    ... [model]
    ... command = ["driver"]
    ... responses = ["y"]
    ... [parameters.a]
    ... distribution = "uniform"
    ... lower = 0.0
    ... upper = 1.0
    ... [[steps]]
    ... type = "sampling"
    ... n_samples = 4
    ... '''
    >>> check_study_paths(parse_study(text, "s.toml"), out_given=True)
    >>> check_study_paths(parse_study(text, "s.toml"))
    Traceback (most recent call last):
    ...
    rotoruq.errors.InputFileError: s.toml, line 4: expected [study] output relative to its \
folder, without '..' (a '..' component), found '../../elsewhere'
    """
    path = study.path
    loc = Locator(study.text)
    try:
        doc: dict[str, Any] = tomllib.loads(study.text) if study.text else {}
    except tomllib.TOMLDecodeError:  # parsed already; a study built by hand has no text
        doc = {}
    base = path.parent if path.name != "<study>" else Path.cwd()

    def table(key: str) -> dict:
        t = doc.get(key, {})
        return t if isinstance(t, dict) else {}

    check_name(study.info.name, what="the study name", path=path,
               line=loc.line("study", "name"))
    for i, step in enumerate(study.steps):
        check_name(step.name, what="a step name", path=path, line=loc.line("steps", i, "name"))
    raw_out = table("study").get("output")
    if raw_out is not None and not out_given:
        check_relative(raw_out, what="[study] output", path=path,
                       line=loc.line("study", "output"))
    if study.store.enabled and not outside_store:
        line = loc.line("store", "path")
        check_relative(study.store.path, what="[store] path (or allow an outside store on "
                       "the command line)", path=path, line=line)
        if out is not None:
            inside(out, study.store.path, what="[store] path", path=path, line=line)
    ext = study.model.external
    if ext is not None:
        if ext.workdir is not None:
            line = loc.line("model", "workdir")
            check_relative(ext.workdir, what="[model] workdir", path=path, line=line)
            if out is not None:
                inside(out, ext.workdir, what="[model] workdir", path=path, line=line)
        for key, words in (("templates", ext.templates), ("files", ext.files)):
            for word in words:
                inside(base, word, what=f"a [model] {key} entry", path=path,
                       line=loc.line("model", key))
    for name, spec in table("data").items():
        if isinstance(spec, dict) and isinstance(spec.get("file"), str):
            line = loc.line("data", name, "file")
            rel = check_relative(spec["file"], what=f"[data.{name}] file", path=path, line=line)
            if (base / rel).exists():  # else a bundled data file (rotoruq/data)
                inside(base, rel, what=f"[data.{name}] file", path=path, line=line)
    steps = doc.get("steps", [])
    for i, spec in enumerate(steps if isinstance(steps, list) else []):
        if isinstance(spec, dict) and isinstance(spec.get("points"), str):
            line = loc.line("steps", i, "points")
            rel = check_relative(spec["points"], what="a step's points file", path=path,
                                 line=line)
            inside(base, rel, what="a step's points file", path=path, line=line)
