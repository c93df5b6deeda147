"""Find and run the MBDyn executable.

rotoruq does not ship or depend on MBDyn: users install it and point rotoruq at it, by order
of precedence with an explicit path (the driver's ``--mbdyn`` option, i.e. a word of the study's
``[model] command``), the ``MBDYN`` environment variable, or ``mbdyn`` on ``PATH``.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import EvaluationError, RotoruqError
from ..evaluation.process_tree import set_parent_death_signal

__all__ = ["MBDynError", "MBDynNotFoundError", "MBDynRun", "find_mbdyn", "run_mbdyn"]

_TAIL = 4000  # characters of MBDyn's output kept in error messages


class MBDynNotFoundError(RotoruqError, FileNotFoundError):
    """No MBDyn executable was given or found."""


class MBDynError(EvaluationError):
    """MBDyn failed, did not converge, or wrote output rotoruq cannot use."""


@dataclass(frozen=True, eq=False)
class MBDynRun:
    """A finished MBDyn run.

    Attributes
    ----------
    prefix : Path
        The output prefix (``<prefix>.rot``, ``.out``, ...).
    wall_time : float
        Seconds the run took.
    output : str
        The tail of its combined stdout and stderr.
    """

    prefix: Path
    wall_time: float
    output: str


def build_prefix_mbdyn() -> Path:
    """Where an MBDyn built by the project's build tool (``tools/build-mbdyn PREFIX``) lives:
    ``$MBDYN_PREFIX/bin/mbdyn``, the prefix ``~/.cache/mbdyn`` by default (as ``.ci/run``)."""
    prefix = os.environ.get("MBDYN_PREFIX") or str(Path.home() / ".cache" / "mbdyn")
    return Path(prefix).expanduser() / "bin" / "mbdyn"


def find_mbdyn(explicit: str | os.PathLike | None = None, *,
               build_prefix: bool = False) -> Path:
    """The MBDyn executable: ``explicit``, else ``$MBDYN``, else ``mbdyn`` on ``PATH``, else
    (with ``build_prefix``, as the benchmarks, scripts and tests do) the build tool's
    install (:func:`build_prefix_mbdyn`).

    An ``explicit`` path that is not an executable file is an error of its own (the caller
    asked for that MBDyn: another one found elsewhere would silently answer instead).
    Raises :class:`MBDynNotFoundError` naming what was tried.

    Parameters
    ----------
    explicit : str or PathLike, optional
        The executable asked for (``--mbdyn``).
    build_prefix : bool, optional
        Also look in the build tool's install (default False).
    """
    if explicit:
        p = Path(explicit).expanduser()
        if p.is_file() and os.access(p, os.X_OK):
            return p.absolute()
        raise MBDynNotFoundError(f"MBDyn executable not found: --mbdyn={str(explicit)!r} is not "
                                 "an executable file")
    tried = []
    for source, cand in (("MBDYN", os.environ.get("MBDYN")),):
        if not cand:
            continue
        p = Path(cand).expanduser()
        if p.is_file() and os.access(p, os.X_OK):
            return p.absolute()
        tried.append(f"{source}={str(cand)!r} (not an executable file)")
    on_path = shutil.which("mbdyn")
    if on_path:
        return Path(on_path)
    tried.append("'mbdyn' on PATH (not found)")
    if build_prefix:
        built = build_prefix_mbdyn()
        if built.is_file() and os.access(built, os.X_OK):
            return built.absolute()
        tried.append(f"the build tool's {str(built)!r} (not found)")
    raise MBDynNotFoundError(
        "MBDyn executable not found; tried " + ", ".join(tried) + ". Install MBDyn and set the "
        "MBDYN environment variable, pass --mbdyn PATH to the driver, or put mbdyn on PATH")


def _die_with_parent() -> None:
    set_parent_death_signal(signal.SIGKILL)


def run_mbdyn(input_file: str | os.PathLike, prefix: str | os.PathLike,
              mbdyn: str | os.PathLike | None = None, timeout: float | None = None) -> MBDynRun:
    """Run ``mbdyn -f input_file -o prefix`` (absolute prefix, so output never lands next to
    the input) in the input file's folder; raise :class:`MBDynError` with the tail of MBDyn's
    output when it exits with a non-zero status or times out.

    Parameters
    ----------
    input_file : str or PathLike
        The MBDyn input file.
    prefix : str or PathLike
        The output prefix (made absolute).
    mbdyn : str or PathLike, optional
        The executable (default: :func:`find_mbdyn`).
    timeout : float, optional
        Seconds the run may take (default None: no limit).

    Returns
    -------
    MBDynRun
        The output prefix, wall time and output tail.
    """
    exe = find_mbdyn(mbdyn)
    input_file, prefix = Path(input_file).absolute(), Path(prefix).absolute()
    t0 = time.perf_counter()
    try:
        # MBDyn dies with its driver, even when a process-group SIGKILL takes the driver first
        proc = subprocess.run([str(exe), "-f", str(input_file), "-o", str(prefix)],
                              cwd=input_file.parent, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout,
                              preexec_fn=_die_with_parent)
    except subprocess.TimeoutExpired:
        raise MBDynError(f"MBDyn did not finish {input_file.name} within {timeout:g} s") from None
    wall = time.perf_counter() - t0
    out = proc.stdout.decode(errors="replace")[-_TAIL:]
    if proc.returncode != 0:
        last = [ln for ln in out.strip().splitlines() if ln.strip()][-3:]
        raise MBDynError(f"MBDyn exited with status {proc.returncode} on {input_file.name}"
                         + (": " + " | ".join(s.strip() for s in last) if last else ""))
    return MBDynRun(prefix, wall, out)
