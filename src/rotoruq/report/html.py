"""The report: one self-contained HTML page (figures embedded as base64 PNG), every figure as
a PNG and an SVG file, every table as CSV; printed from a browser, the page makes a clean PDF
(print CSS).

``write_report([results_dir, ...], report_dir)`` reads saved study outputs (see
:mod:`rotoruq.results`) and writes ``report_dir/index.html``,
``figures/<study>_<figure>.png`` and ``.svg`` and ``tables/``. It only reads results:
``rotoruq report RESULTS`` rebuilds it at any time. Every study gets a table per step, its
figures and a first screen with a verdict computed from the run (validation comparisons
within their uncertainty, failed self-checks, failed evaluations, diagnostic warnings). An
application built on rotoruq adds its own findings through ``application=``
(:mod:`rotoruq.report.application`): the reference study's claims, for instance, come from
:mod:`rotoruq.reference`, which this module never imports.
"""

from __future__ import annotations

import base64
import datetime as _dt
import json
import logging
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from ..render.figures import FigureContext
from ..results import (
    STUDY_INFO,
    StepResult,
    is_study_dir,
    load_results,
    study_infos,
)
from ..safety import SafeFolder
from ..steps.bayes_calibration import posterior_record
from .application import Addition, Application, ReportData, Section
from .escape import slug
from .escape import text as e
from .hooks import rendering
from .provenance import failed_evaluations, git_commit
from .skipped import skipped_note, skipped_steps
from .steptables import step_tables, table_csv
from .sweeps import sweep_figures
from .tables import fmt, step_table_html
from .verdict import verdict_lines

__all__ = ["write_report", "find_study_dirs", "prerender_figures"]

log = logging.getLogger(__name__)

_CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:auto;padding:1em;color:#222}
table{border-collapse:collapse;margin:.5em 0;font-size:12px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
th{background:#f3f3f3} td.l,th.l{text-align:left}
td.ok{background:#e5f5e0} td.off{background:#fee8c8}
.note{font-size:12px;color:#555;margin-top:0}
figure{margin:1em 0} figure img{max-width:100%}
figcaption{font-size:12px;color:#444}
.st-holds{color:#1a7f37;font-weight:bold} .st-warn{color:#9a6700;font-weight:bold}
.st-fails{color:#b42318;font-weight:bold} .st-na{color:#777}
ul.why{margin:0;padding-left:1.2em;font-size:11px;text-align:left}
nav.toc{font-size:13px}
details{font-size:11px;text-align:left}
section.first{border:1px solid #ccc;padding:.5em 1em;margin:1em 0}
p.counts{font-size:16px} ol.verdict{font-size:13px;padding-left:1.5em}
ol.verdict li{margin:2px 0} details.prov,details.toc{font-size:12px}
figcaption a{color:#555}
@media print{
body{max-width:none;margin:0;padding:0;font-size:11px}
details.toc,figcaption .files{display:none}
figure,table,section.first,ol.verdict li{break-inside:avoid}
h1,h2,h3,h4{break-after:avoid}
figure img{max-width:100%;max-height:23cm}
a{color:inherit;text-decoration:none}
td.ok,td.off,th,.st-holds,.st-warn,.st-fails{-webkit-print-color-adjust:exact;
print-color-adjust:exact}
}
"""

def find_study_dirs(root: str | Path) -> list[Path]:
    """Study output folders under ``root`` (``root`` itself when it is one)."""
    root = Path(root)
    if is_study_dir(root):
        return [root]
    return sorted(p.parent for p in root.glob(f"*/{STUDY_INFO}"))


def _recorded(info: dict, what: str) -> dict:
    """``study.json``'s record of the model: ``values`` (preset fields and nominal airfoil
    coefficients) or ``curves`` (reference curves), written by the run."""
    return dict((info.get("model") or {}).get(what) or {})


#: PNG resolution [dots per inch]: sharp on a high-density screen and in a printed page.
PNG_DPI = 150


#: zlib level of the PNGs: level 3 on RGB pixels makes files the size of Matplotlib's default
#: (RGBA, level 6) in about two thirds of the encoding time (benchmarks/figure_cpu.py).
PNG_COMPRESS_LEVEL = 3


def _png(fig) -> bytes:
    """The figure as PNG at :data:`PNG_DPI`: the pixels ``savefig`` draws, written without
    their alpha channel when every pixel is opaque (the report's figures are: their
    background is white), with Matplotlib's metadata (:func:`_png_file`)."""
    import io

    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=PNG_DPI)
    raw = buf.getbuffer()
    # the size of the image Agg drew (the figure's size in pixels, truncated)
    width, height = int(canvas.renderer.width), int(canvas.renderer.height)
    if len(raw) != 4 * width * height:
        raise RuntimeError(f"{len(raw)} bytes of RGBA for a {width} x {height} figure")
    rgba = np.frombuffer(raw, dtype=np.uint8).reshape(height, width, 4)
    opaque = bool(rgba[..., 3].min() == 255)
    return _png_file(rgba[..., :3] if opaque else rgba, PNG_DPI)


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    import struct
    import zlib

    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data)))


def _png_file(pixels, dpi: float) -> bytes:
    """A PNG file of ``pixels``: 8 bits per channel, every row unfiltered, zlib level
    :data:`PNG_COMPRESS_LEVEL`, with the resolution ``dpi`` [dots per inch] and Matplotlib's
    ``Software`` text.

    Pillow tries the five PNG filters on every row and keeps the best: on the report's
    figures (white, lines and text) that wins nothing over no filter (the files are the same
    size, 7.0 MB for the 45 figures of the full reproduction) and costs more than half of the
    encoding time (1.23 -> 0.48 CPU-s).

    Parameters
    ----------
    pixels : ndarray of uint8, shape (height, width, 3) or (height, width, 4)
        RGB or RGBA pixels, rows from the top.
    dpi : float
        The image's resolution [dots per inch].

    Returns
    -------
    bytes
        The PNG file.
    """
    import struct
    import zlib

    import matplotlib as mpl
    import numpy as np

    height, width, channels = pixels.shape
    if pixels.dtype != np.uint8 or channels not in (3, 4):
        raise ValueError(f"8-bit RGB or RGBA pixels expected, got {pixels.dtype} "
                         f"{pixels.shape}")
    rows = np.zeros((height, 1 + width * channels), dtype=np.uint8)  # filter byte 0: none
    rows[:, 1:].reshape(height, width, channels)[...] = pixels
    software = f"Matplotlib version{mpl.__version__}, https://matplotlib.org/"
    per_metre = int(dpi / 0.0254 + 0.5)
    return b"".join([
        b"\x89PNG\r\n\x1a\n",
        _png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8,
                                        2 if channels == 3 else 6, 0, 0, 0)),
        _png_chunk(b"tEXt", b"Software\0" + software.encode("latin-1")),
        _png_chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
        _png_chunk(b"IDAT", zlib.compress(rows.data, PNG_COMPRESS_LEVEL)),
        _png_chunk(b"IEND", b""),
    ])


def _svg(fig) -> bytes:
    """The figure as SVG, the same bytes on every drawing: no date, and element ids hashed
    with a fixed salt (matplotlib's default salt is random)."""
    import io

    import matplotlib as mpl

    buf = io.BytesIO()
    # text as SVG text (the strings, in the figure's font), not a path per glyph
    with mpl.rc_context({"svg.hashsalt": "rotoruq", "svg.fonttype": "none"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def _lay_out(fig) -> None:
    """Run the figure's layout engine once, measuring the text as the PNG draws it (at
    :data:`PNG_DPI`), then detach it, so that neither file's drawing lays the figure out
    again: ``savefig`` of a figure with a layout engine draws it twice (a measuring pass,
    then the file), and the drawing runs the engine again each time."""
    import matplotlib as mpl
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    engine = fig.get_layout_engine()
    if engine is not None:
        dpi = fig.dpi
        fig.set_dpi(PNG_DPI)
        FigureCanvasAgg(fig)  # the renderer the engine measures with is the PNG's
        try:
            engine.execute(fig)
        finally:
            fig.set_dpi(dpi)  # the SVG's raster parts keep the figure's own resolution
        # None is "no engine" only while the rc defaults ask for none
        with mpl.rc_context({"figure.autolayout": False,
                             "figure.constrained_layout.use": False}):
            fig.set_layout_engine(None)
    _fix_ticks(fig)


def _fix_ticks(fig) -> None:
    """Pin every axis's major ticks where its locator puts them in the laid-out figure, with
    the labels (and offset, e.g. ``1e-3``) its formatter gives them: the two drawings (PNG,
    SVG) then place the same ticks without running the locator and formatter again. The
    axes' sizes and limits are final here, so the ticks are the ones each drawing would
    compute. Only the ticks inside the view are kept (the formatter still sees all the
    locator's, as a drawing's does): a drawing makes a tick's artists for every location
    its locator gives and draws those inside the view alone, so the others cost artists
    that are never drawn."""
    from matplotlib.ticker import FixedFormatter, FixedLocator

    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if not axis.get_visible() or isinstance(axis.get_major_locator(), FixedLocator):
                continue
            if axis.get_scale() != "linear":
                continue
            locs = axis.get_majorticklocs()
            formatter = axis.get_major_formatter()
            labels = formatter.format_ticks(locs)
            # the test a drawing applies to each tick (linear scale: no transform): inside
            # the view to 1e-10 of its span
            lo, hi = sorted(axis.get_view_interval())
            tol = (hi - lo) * 1e-10
            shown = [k for k, loc in enumerate(locs) if lo - tol <= loc <= hi + tol]
            fixed = FixedFormatter([labels[k] for k in shown])
            fixed.set_offset_string(formatter.get_offset())
            axis.set_major_locator(FixedLocator([locs[k] for k in shown]))
            axis.set_major_formatter(fixed)


@dataclass(frozen=True, eq=False)
class _Rendered:
    """A figure drawn once: its PNG, its SVG and the axis labels the page records beside it."""

    name: str
    caption: str
    png: bytes
    svg: bytes
    xlabels: tuple[str, ...]
    ylabels: tuple[str, ...]


def _render(figs) -> list[_Rendered]:
    out = []
    for f in figs:
        shown = [ax for ax in f.figure.axes if ax.axison]
        # laid out once for both files (the SVG keeps the PNG's layout): each file is then
        # one drawing pass
        _lay_out(f.figure)
        out.append(_Rendered(f.name, f.caption, _png(f.figure), _svg(f.figure),
                             tuple(sorted({a.get_xlabel() for a in shown} - {""})),
                             tuple(sorted({a.get_ylabel() for a in shown} - {""}))))
    return out


@contextmanager
def _collected_once() -> Iterator[None]:
    """Build and draw figures with Python's cyclic garbage collector paused, then collect
    what they left in one pass over the objects made meanwhile.

    A Matplotlib figure is a web of reference cycles (artists, their figure, transforms,
    callbacks): many thousands of objects that live as long as the drawing, so they reach
    the collector's oldest generation and die there, and each automatic full collection
    meanwhile walks every object of the process (the imported modules' too): 1.5 of the
    ~20 CPU-s of the full reproduction's figures in one process. Here the objects alive
    before are set aside (:func:`gc.freeze`), and the one collection at the end walks only
    the drawing's own (0.5 CPU-s in all); the figures are freed when the block ends, as the
    automatic collections would have freed them. A collector the caller has paused, or
    objects it has frozen, are left as they are (with a freeze of its own, the collection
    at the end walks every object once).
    """
    import gc

    if not gc.isenabled():
        yield
        return
    freeze = gc.get_freeze_count() == 0
    if freeze:
        gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        try:
            gc.collect()
        finally:
            if freeze:
                gc.unfreeze()
            gc.enable()


# Below this many steps with figures, a second process costs more than it saves.
_PARALLEL_MIN_STEPS = 6


class _ReadSteps(Mapping[str, StepResult]):
    """A study's steps as a figure hook sees them, noting the other steps it looked at (by
    name, looked up or asked about; a walk over them all notes them all), so that its
    figures are kept only as long as those steps are unchanged, not every step of the study."""

    def __init__(self, steps: Mapping[str, StepResult], own: str) -> None:
        self._steps, self._own = steps, own
        self.read: set[str] = set()

    def _note(self, name: str) -> None:
        if name != self._own:
            self.read.add(name)

    def __getitem__(self, name: str) -> StepResult:
        self._note(name)
        return self._steps[name]

    def __contains__(self, name: object) -> bool:
        if isinstance(name, str):
            self._note(name)
        return name in self._steps

    def __iter__(self):  # type: ignore[no-untyped-def]
        for name in self._steps:
            self._note(name)
        return iter(self._steps)

    def __len__(self) -> int:
        return len(self._steps)


@dataclass(frozen=True)
class _Drawn:
    """One step's rendered figures and the other steps of its study the hook read."""

    figures: list[_Rendered]
    reads: tuple[str, ...]


def draw_step(hook: Callable, steps: Mapping[str, StepResult], step: str, study: str,
              labels: Mapping[str, str], units: Mapping[str, str],
              beside: Mapping[str, Any] | None, curves: Mapping[str, Any]) -> _Drawn:
    """Draw and render one step's figures (in this process or in the figure worker), noting
    which other steps of the study the hook read."""
    from .plots import step_figures

    seen = _ReadSteps(steps, step)
    ctx = FigureContext(study, seen, labels, units, beside, curves)
    with _collected_once():
        figures = _render(step_figures(hook, steps[step], ctx))
    return _Drawn(figures, tuple(sorted(seen.read)))


def _fingerprints(steps: Mapping[str, StepResult]) -> dict[str, str]:
    return {n: r.fingerprint for n, r in steps.items()}


def _anchor(*parts: str) -> str:
    """An id from study-supplied names: each part through :func:`~.escape.slug`."""
    return "-".join(slug(p) for p in parts)


def _steps_summary(steps: dict[str, StepResult], anchors: dict[str, str]) -> str:
    rows = []
    for s in steps.values():
        rows.append(
            f"<tr><td class=l><a href='#{anchors[s.name]}'>{e(s.name)}</a></td>"
            f"<td>{e(s.type)}</td>"
            f"<td class=l>{e(s.meta.get('title') or '')}</td>"
            f"<td>{e(s.meta.get('n_evaluations', '-'))}</td>"
            f"<td>{_num(s.meta.get('seconds'))}</td></tr>")
    return ("<table><tr><th class=l>step</th><th>type</th><th class=l>what</th>"
            f"<th>evaluations</th><th>seconds</th></tr>{''.join(rows)}</table>")


def _noise_note(steps: dict[str, StepResult]) -> str:
    parts = []
    for s in steps.values():
        rec = posterior_record(s) if s.type == "bayes_calibration" else None
        if rec is not None and rec.names_out:
            what = ", ".join(f"{r} {fmt(float(v))}"
                             for r, v in zip(rec.names_out, rec.noise_std, strict=True))
            parts.append(f"{e(s.name)}: {e(rec.noise_model)} ({e(what)})")
    if not parts:
        return ""
    return ("<p class=note><b>Noise model of the calibrations</b> (data std devs in response "
            "units): " + "; ".join(parts) + ".</p>")


# The page needs no script: inline <script> and event handlers are refused, images come
# only from data: URLs (the JSON data block is not a script and is never executed).
CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'none'; "
       "base-uri 'none'; form-action 'none'")

def _num(v: Any) -> str:
    """A saved number for the page (anything else escaped as text)."""
    if isinstance(v, int | float) and not isinstance(v, bool):
        return fmt(float(v))
    return e("-" if v is None else v)


def _first_screen(studies: Mapping[str, Mapping[str, StepResult]], infos: Mapping[str, dict],
                  labels: Mapping[str, Mapping[str, str]], extra: str = "") -> str:
    """The verdict (the run's own, then an application's), the V&V table and the
    provenance."""
    out = ["<section class=first id='verdict'><h2>Verdict</h2>", run_verdict(studies, labels),
           extra, _vv_section(studies, labels), _provenance(studies, infos), "</section>"]
    return "".join(out)


def run_verdict(studies: Mapping[str, Mapping[str, StepResult]],
                labels: Mapping[str, Mapping[str, str]] | None = None) -> str:
    """The report's own verdict as an HTML list (:func:`~.verdict.verdict_lines`), each item
    carrying its counts as ``data-`` attributes."""
    items = []
    for line in verdict_lines(studies, labels):
        attrs = "".join(f" data-{k}='{v}'" for k, v in line.counts.items())
        # a failed self-check is a finding, not a warning: marked as one on the first screen
        failed = (line.counts.get("failed") if line.check == "self-check"
                  else line.counts.get("on_failed_self_check"))
        mark = "<span class=st-fails>self-check FAILED</span> " if failed else ""
        items.append(f"<li data-check='{line.check}'{attrs}>{mark}<b>{e(line.title)}</b>: "
                     f"{e(line.text)}</li>")
    return "<ul class=run-verdict>" + "".join(items) + "</ul>"


def _vv_section(studies: Mapping[str, Mapping[str, StepResult]],
                labels: Mapping[str, Mapping[str, str]]) -> str:
    """What every step of type ``validation`` shows (its type's tables), or a clear slot."""
    body = []
    for study, steps in studies.items():
        for s in steps.values():
            if s.type != "validation":
                continue
            body.append(f"<p class=note>{e(study)} / {e(s.name)}: "
                        f"{e(s.meta.get('title') or '')}</p>")
            body += [step_table_html(t) for t in step_tables(s, labels.get(study))]
    if not body:
        body = ["<p class=note id='vv-slot'>No <code>validation</code> step in these results: "
                "no comparison error E = S - D with its validation uncertainty to show. Add a "
                "step of type <code>validation</code> to the study.</p>"]
    return "<h3 id='vv'>Validation (V&amp;V)</h3>" + "".join(body)


def _provenance(studies: Mapping[str, Mapping[str, StepResult]],
                infos: Mapping[str, dict]) -> str:
    """rotoruq's version and commit, each study's seed, every step's settings and its failed
    evaluations, folded."""
    from .. import __version__

    commit = git_commit()
    n_failed, recorded, unrecorded = 0, 0, 0
    rows = []
    for study, steps in studies.items():
        info = infos[study]
        trs = []
        for s in steps.values():
            fails = failed_evaluations(s)
            if fails is None:
                failed = "not recorded"
                unrecorded += 1
            else:
                n_failed += fails[0]
                recorded += 1
                failed = str(fails[0]) + "".join(
                    f"<br>{e(r)} ({k})" for r, k in sorted(fails[1].items()))
            settings = json.dumps(s.meta.get("options") or {}, sort_keys=True, default=str)
            trs.append(f"<tr><td class=l>{e(s.name)}</td><td class=l>{e(s.type)}</td>"
                       f"<td class=l><code>{e(settings)}</code></td>"
                       f"<td>{_num(s.meta.get('n_evaluations'))}</td><td class=l>{failed}</td>"
                       f"<td class=l>{e(s.meta.get('code_version') or '-')}</td></tr>")
        rows.append(
            f"<p><b>{e(study)}</b>: seed {e(info.get('seed', '-'))}"
            f"{', quick' if info.get('quick') else ''}; study file "
            f"{e(info.get('study_file') or '-')}</p>"
            "<table><tr><th class=l>step</th><th class=l>type</th><th class=l>settings</th>"
            "<th>evaluations</th><th class=l>failed evaluations (reasons)</th>"
            "<th class=l>code version</th></tr>" + "".join(trs) + "</table>")
    seeds = ", ".join(f"{e(n)} {e(infos[n].get('seed', '-'))}" for n in studies)
    return (f"<details class=prov id='provenance'><summary><b>Provenance</b>: report by rotoruq "
            f"{e(__version__)}, commit {e(commit or 'not available')} (the version that "
            f"computed each step: its code version below); seeds: {seeds}; "
            f"<span data-failed='{n_failed}'>{n_failed} failed evaluations in the {recorded} "
            f"steps that record them</span>"
            + (f" ({unrecorded} steps do not)" if unrecorded else "") + "</summary>"
            + "".join(rows) + "</details>")


def _figure_html(f: _Rendered, key: str) -> str:
    b64 = base64.b64encode(f.png).decode()
    return (f"<figure id='fig-{e(key)}' data-xlabels='{e(json.dumps(list(f.xlabels)))}' "
            f"data-ylabels='{e(json.dumps(list(f.ylabels)))}'><img alt='{e(f.caption)}' "
            f"src='data:image/png;base64,{b64}'><figcaption>{e(f.caption)} <span class=files>"
            f"(<a href='figures/{e(key)}.svg'>SVG</a>, <a href='figures/{e(key)}.png'>PNG</a>)"
            "</span></figcaption></figure>")


def write_report(results_dirs: Sequence[str | Path], report_dir: str | Path,
                 title: str | None = None, *, workers: int | None = None,
                 application: Application | None = None) -> Path:
    """Write the report of the given study output folders; returns ``index.html``.

    The report only reads what the runs recorded (step results and ``study.json``, which
    holds the model's properties and reference curves): it never builds or runs a model.
    Progress (a line per study and per figure batch) goes to the ``rotoruq.report.html``
    logger at INFO.

    Parameters
    ----------
    results_dirs : sequence of str or Path
        Results folders written by ``rotoruq run`` (one per study), in the report's order.
    report_dir : str or Path
        The folder to write: ``index.html``, ``figures/`` (PNG and SVG) and ``tables/``
        (created when missing).
    title : str, optional
        Page title (default: the application's when it gives one, else the studies' names).
    workers : int, optional
        Processes that draw the figures (each figure is drawn once, as PNG and SVG).
        Default: two when the machine has two or more cores and at least six steps have
        figures, else one (this process). The page and every file are the same whatever the
        count.
    application : Application, optional
        What an application built on rotoruq adds (see
        :class:`rotoruq.report.application.Application`): for the studies it ``covers``, its
        title, verdict, sections, files and the numbers the figures draw beside the run's.
        None: the report of the run alone.

    Returns
    -------
    Path
        The report's ``index.html``.
    """
    t_start = time.perf_counter()
    report_dir = Path(report_dir)
    # every folder and file of the report is made through descriptors that never follow a
    # symlink, each file atomically: a link planted while the run was in its steps is
    # refused naming it, and a full disk leaves the previous file whole
    with SafeFolder(report_dir) as out, out.folder("figures") as fig_dir, \
            out.folder("tables") as tab_dir:
        return _write_report(results_dirs, report_dir, out, fig_dir, tab_dir, title, workers,
                             application, t_start)


def _write_report(results_dirs: Sequence[str | Path], report_dir: Path, out: SafeFolder,
                  fig_dir: SafeFolder, tab_dir: SafeFolder, title: str | None,
                  workers: int | None, application: Application | None,
                  t_start: float) -> Path:
    studies: dict[str, dict[str, StepResult]] = {}
    infos: dict[str, dict] = {}
    folders: dict[str, str] = {}
    # two folders of one study name: an error naming both, never one dropped in silence
    found = study_infos([f for d in results_dirs for f in find_study_dirs(d)])
    for name, (folder, info) in found.items():
        studies[name] = load_results(folder)
        infos[name] = info
        folders[name] = str(folder)
    labels = _labels(infos)
    covered = ([n for n, i in infos.items() if application.covers(i)]
               if application is not None else [])
    # figures first: a worker process draws them while this one builds the tables; the
    # figures of steps whose study, context and drawing code did not change come from the
    # cache of the earlier reports (or of prerender_figures)
    from .figcache import FigureCache

    cache = FigureCache(report_dir, out)
    contexts = _figure_contexts(infos, application)
    jobs, keys = _figure_jobs(studies, infos, application, cache, contexts)
    cached = {}
    for j in jobs:
        hit = cache.get(keys[j.study, j.step], _Rendered, _fingerprints(studies[j.study]))
        if hit is not None:
            cached[j.study, j.step] = hit
    log.info("report: %d of %d figure jobs from the cache of earlier reports", len(cached),
             len(jobs))
    drawing = _FigureDrawing(studies, folders,
                             [j for j in jobs if (j.study, j.step) not in cached], workers)
    drawn: dict[tuple[str, str], list[_Rendered]] | None = None
    try:
        added = Addition()
        if application is not None and covered:
            added = application.build(ReportData({n: studies[n] for n in covered},
                                                 {n: infos[n] for n in covered},
                                                 {n: labels[n] for n in covered}))
        if title is None:
            if added.title:
                title = added.title
            else:
                title = "rotoruq: " + ", ".join(
                    f"{n}" + (f" ({infos[n].get('description')})" if infos[n].get("description")
                              else "") for n in infos)

        toc: list[tuple[int, str, str]] = []  # (level, anchor, text)
        body: list[str] = []

        def heading(level: int, text: str, anchor: str) -> None:
            toc.append((level, anchor, text))
            body.append(f"<h{level} id='{anchor}'>{e(text)}</h{level}>")

        def section(sec: Section) -> None:
            heading(sec.level, sec.title, sec.anchor)
            if sec.html:
                body.append(sec.html)

        quick = [n for n, i in infos.items() if i.get("quick")]
        first = ""
        if quick:
            first = (f"<p><b>Quick run</b> ({e(', '.join(quick))}): small samples; the "
                     "numbers show the pipeline works, not the converged values.</p>")
        first += _first_screen(studies, infos, labels, added.verdict)
        for sec in added.sections:
            section(sec)
        for rel, text in added.files.items():
            parts = PurePosixPath(rel).parts
            if not parts or PurePosixPath(rel).is_absolute() or ".." in parts:
                raise ValueError(f"an application's file outside the report folder: {rel!r}")
            _write_nested(out, parts, text.encode("utf-8"))

        unrendered = sorted({s.type for steps in studies.values() for s in steps.values()
                             if rendering(s.type).tables is None})
        if unrendered:
            log.warning("report: no renderers registered for step type(s) %s: key/value tables "
                        "only (importing rotoruq.study registers the built-in step types)",
                        ", ".join(unrendered))
        for name, steps in studies.items():
            info = infos[name]
            log.info("report: %s (%d steps)", name, len(steps))
            sid = _anchor("study", name)
            heading(2, f"Study {name}: {info.get('description', '')}".rstrip(": "), sid)
            anchors = {s: _anchor(sid, "step", s) for s in steps}
            body.append(_steps_summary(steps, anchors))
            body.append(_noise_note(steps))
            heading(3, "Results by step", _anchor(sid, "steps"))
            for s in steps.values():
                heading(4, f"{s.name} ({s.type}): {s.meta.get('title') or ''}".rstrip(": "),
                        anchors[s.name])
                for k, t in enumerate(step_tables(s, labels.get(name))):
                    tab_dir.write(f"{slug(name)}_{slug(s.name)}_{k + 1}.csv",
                                  table_csv(t).encode("utf-8"))
                    body.append(step_table_html(t))
            for skipped, why in skipped_steps(info, steps):  # rotoruq.report.skipped
                heading(4, f"{skipped}: skipped", _anchor(sid, "step", skipped))
                body.append(skipped_note(info, skipped, why))
            for sec in added.study_sections.get(name, ()):
                section(sec)
            t0 = time.perf_counter()
            if drawn is None:
                drawn = {}
                for job_key, got in drawing.finish().items():
                    fps = _fingerprints(studies[job_key[0]])
                    cache.put(keys.get(job_key), got.figures,
                              {n: fps.get(n, "") for n in got.reads})
                    drawn[job_key] = got.figures
                drawn.update(cached)
                cache.prune()
                cache.close()
            figs = [f for step in steps for f in drawn.get((name, step), [])]
            # steps of one type that differ in one fixed input: drawn against it
            with _collected_once():
                figs += _render(sweep_figures(
                    steps, {s: r.type for s, r in steps.items()},
                    info.get("step_fixed") or {}, FigureContext(name, steps, *contexts[name])))
            if figs:
                heading(3, "Figures", _anchor(sid, "figures"))
            for f in figs:
                key = f"{slug(name)}_{slug(f.name)}"  # two studies may both have a step "bayes"
                fig_dir.write(f"{key}.png", f.png)
                fig_dir.write(f"{key}.svg", f.svg)
                toc.append((4, f"fig-{key}", f.caption))
                body.append(_figure_html(f, key))
            log.info("report: %s: %d figures (%.1f s waited)", name, len(figs),
                     time.perf_counter() - t0)
    finally:
        drawing.close()

    nav = "".join(
        f"<li style='margin-left:{(lvl - 2) * 1.2}em'><a href='#{a}'>{e(txt)}</a>"
        "</li>" for lvl, a, txt in toc)
    head = [f"<h1>{e(title)}</h1>",
            f"<p class=note>Generated {_dt.datetime.now().isoformat(timespec='seconds')} from "
            f"{', '.join(e(p) for p in results_dirs)}.</p>", first,
            f"<details class=toc><summary>Contents ({len(toc)} sections, tables and figures)"
            f"</summary><nav class=toc id='toc'><ul>{nav}</ul></nav></details>"]
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<meta http-equiv='Content-Security-Policy' content=\"{CSP}\">"
            f"<title>{e(title)}</title><style>{_CSS}</style></head><body>"
            + "\n".join(head + body) + "</body></html>")
    cache.close()  # when no study had figures to draw
    index = out.write("index.html", page.encode("utf-8"), sync=True)
    log.info("report: written in %.1f s", time.perf_counter() - t_start)
    return index



def _labels(infos: Mapping[str, dict]) -> dict[str, dict[str, str]]:
    return {n: {k: v.get("label") or k for k, v in i.get("parameters", {}).items()}
            for n, i in infos.items()}


def _figure_contexts(infos: Mapping[str, dict], application: Application | None
                     ) -> dict[str, tuple]:
    """Per study, what its figures are drawn with besides its results: the labels, the
    parameters' units, the numbers the application draws beside the run's and the recorded
    curves (the context of a :class:`FigureContext` and part of each figure's cache key)."""
    labels = _labels(infos)
    units = {n: {k: v.get("unit") for k, v in i.get("parameters", {}).items() if v.get("unit")}
             for n, i in infos.items()}
    beside = {n: application.beside(n, i) for n, i in infos.items()
              if application is not None and application.covers(i)}
    return {n: (labels.get(n, {}), units.get(n, {}), beside.get(n), _recorded(i, "curves"))
            for n, i in infos.items()}


def _figure_jobs(studies: Mapping[str, Mapping[str, StepResult]], infos: Mapping[str, dict],
                 application: Application | None, cache: Any,
                 contexts: Mapping[str, tuple] | None = None,
                 ) -> tuple[list[_Job], dict[tuple[str, str], str | None]]:
    """Every step's figure job and its key in ``cache`` (a :class:`FigureCache`). A study's
    jobs and keys depend on that study alone (its results, labels, units, curves and what
    the application draws beside it), so they are the same in a report of that study alone
    and in one of several (:func:`prerender_figures` relies on it)."""
    from ._figworker import hook_name

    if contexts is None:
        contexts = _figure_contexts(infos, application)
    jobs = [_Job(study, name, hook, contexts[study])
            for study, steps in studies.items() for name, res in steps.items()
            if (hook := rendering(res.type).figures) is not None]
    keys = {(j.study, j.step): cache.key(
        j.study, j.step, hook_name(j.hook), studies[j.study][j.step].fingerprint, j.context)
        for j in jobs}
    return jobs, keys


def prerender_figures(results_dir: str | Path, report_dir: str | Path, *,
                      application: Application | None = None,
                      part: tuple[int, int] = (0, 1)) -> int:
    """Draw the figures of the studies saved under ``results_dir`` into the figure cache of
    ``report_dir``, for a later :func:`write_report` of these studies (alone or with others)
    to take instead of drawing them: ``rotoruq reproduce`` draws a chapter's figures as soon
    as that chapter is done, while the other chapters still run.

    Only adds to the cache (never prunes it: the report that follows does); figures already
    cached are not drawn again. The files are the same bytes the report would draw itself:
    the cache key covers the study's results, the figure's context and the drawing code.

    Parameters
    ----------
    results_dir : str or Path
        A study's results folder (or a folder of them).
    report_dir : str or Path
        The report folder the later :func:`write_report` writes.
    application : Application, optional
        The application the later report is given (its numbers are drawn beside the run's).
    part : (int, int), optional
        ``(k, n)``: draw only every ``n``-th figure job from the ``k``-th, so that ``n``
        processes share one study's figures (default: all of them).

    Returns
    -------
    int
        The number of figure jobs (steps with figures) drawn, cached ones not counted.

    Examples
    --------
    >>> import tempfile
    >>> prerender_figures(tempfile.mkdtemp(), tempfile.mkdtemp())  # no study: nothing
    0
    """
    from .figcache import FigureCache

    found = study_infos(find_study_dirs(results_dir))
    studies = {name: load_results(folder) for name, (folder, _) in found.items()}
    infos = {name: info for name, (_, info) in found.items()}
    # the report folder made and the cache opened in it as write_report does, never
    # through a link
    with SafeFolder(report_dir) as out, FigureCache(report_dir, out) as cache:
        jobs, keys = _figure_jobs(studies, infos, application, cache)
        k, n = part
        if not 0 <= k < n:
            raise ValueError(f"part must be (k, n) with 0 <= k < n, got {part!r}")
        drawn = 0
        for j in jobs[k::n]:
            key, fps = keys[j.study, j.step], _fingerprints(studies[j.study])
            if key is None or cache.get(key, _Rendered, fps) is not None:
                continue
            got = draw_step(j.hook, studies[j.study], j.step, j.study, *j.context)
            cache.put(key, got.figures, {n: fps.get(n, "") for n in got.reads})
            drawn += 1
    log.info("report: %d figure jobs of %s drawn ahead of the report", drawn, results_dir)
    return drawn


def _write_nested(folder: SafeFolder, parts: Sequence[str], data: bytes) -> None:
    """Write ``data`` at the relative path ``parts`` below ``folder``, folders made on the
    way, none of them followed if it is a symlink."""
    if len(parts) == 1:
        folder.write(parts[0], data)
        return
    with folder.folder(parts[0]) as sub:
        _write_nested(sub, parts[1:], data)


@dataclass(frozen=True, eq=False)
class _Job:
    study: str
    step: str
    hook: Callable
    context: tuple  # FigureContext's labels, units, beside, curves


class _FigureDrawing:
    """Every step's figures, drawn once, by this process and ``workers - 1`` worker
    subprocesses (:mod:`rotoruq.report._figworker`) that claim jobs from the other end of
    the list. The workers start first, so they draw while this process builds the tables."""

    def __init__(self, studies: dict[str, dict[str, StepResult]], folders: dict[str, str],
                 jobs: list[_Job], workers: int | None):
        from ._figworker import JOBS_FILE, hook_name

        self.studies, self.jobs = studies, jobs
        if workers is None:
            workers = 2 if (os.cpu_count() or 1) >= 2 and len(jobs) >= _PARALLEL_MIN_STEPS else 1
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        self.job_dir: Path | None = None
        self.procs: list[subprocess.Popen] = []
        names = [hook_name(j.hook) for j in jobs]
        shared = [i for i, n in enumerate(names) if n is not None]
        if workers == 1 or not shared:
            return
        self.job_dir = Path(tempfile.mkdtemp(prefix="rotoruq-figures-"))
        spec = [{"study": jobs[i].study, "step": jobs[i].step, "hook": names[i],
                 "folder": folders[jobs[i].study], "context": list(jobs[i].context)}
                for i in shared]
        self.shared = shared
        (self.job_dir / JOBS_FILE).write_text(json.dumps(spec), encoding="utf-8")
        for _ in range(workers - 1):
            self.procs.append(subprocess.Popen(
                [sys.executable, "-m", "rotoruq.report._figworker", str(self.job_dir)],
                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE))

    def finish(self) -> dict[tuple[str, str], _Drawn]:
        """Draw what the workers have not claimed, wait for them, collect (study, step) ->
        rendered figures. A worker that fails leaves its jobs to this process."""
        from ._figworker import claim

        out: dict[tuple[str, str], _Drawn] = {}
        mine = set(range(len(self.jobs)))
        if self.job_dir is not None:
            mine -= set(self.shared)
        for i in sorted(mine):
            out[self._key(i)] = self._draw(i)
        if self.job_dir is not None:
            for k in reversed(range(len(self.shared))):  # the workers work from the front
                if not claim(self.job_dir, k):
                    break
                mine.add(self.shared[k])
                out[self._key(self.shared[k])] = self._draw(self.shared[k])
        log.info("report: %d of %d figure jobs drawn here, the rest by %d worker(s)",
                 len(mine), len(self.jobs), len(self.procs))
        if self.job_dir is not None:
            try:
                for proc in self.procs:
                    _, err = proc.communicate()
                    if proc.returncode != 0:
                        log.warning("report: a figure worker failed (exit %s); drawing its "
                                    "figures here: %s", proc.returncode,
                                    err.decode(errors="replace").strip()[-2000:])
                for k, i in enumerate(self.shared):
                    if i in mine:
                        continue
                    done = self.job_dir / f"{k}.pkl"
                    out[self._key(i)] = (pickle.loads(done.read_bytes()) if done.is_file()
                                         else self._draw(i))
            finally:
                self.close()
        return out

    def close(self) -> None:
        """Stop workers still running (after an error) and remove the job folder."""
        for proc in self.procs:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        if self.job_dir is not None:
            shutil.rmtree(self.job_dir, ignore_errors=True)

    def _key(self, i: int) -> tuple[str, str]:
        return self.jobs[i].study, self.jobs[i].step

    def _draw(self, i: int) -> _Drawn:
        j = self.jobs[i]
        return draw_step(j.hook, self.studies[j.study], j.step, j.study, *j.context)
