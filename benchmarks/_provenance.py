"""What a saved benchmark result measured: the commit and the identity of the code it exercised.

Every benchmark (and every script under scripts/ whose JSON the docs quote) adds
``"provenance": provenance()`` to the JSON it saves::

    {"commit": "79b8386...", "dirty": false, "date": "2025-06-01T12:00:00+00:00",
     "script": "benchmarks/gp_fit.py",
     "modules": {"rotoruq.methods.surrogate": "f713dec8425b6c05"},
     "files": {"rotoruq/methods/surrogate.py": "3a...", "epoch:methods": "1", ...}}

``modules`` are the rotoruq modules the script imports (``identity.script_modules``), each with
the digest of the code it imports, transitively, through every layer
(``identity.module_digests``: the project's one home for "the code a thing depends on", the
same digests that key stored evaluations and step fingerprints); ``files`` are those parts
one by one, so that a stale result names what changed.

:func:`stale` recomputes the digests: the modules whose code changed since the measurement,
each with the files that changed. The docs show it under every number printed from the JSON
(``docs/_ext/generated_blocks.py``, at build time) and ``tests/test_benchmark_provenance.py``
lists it. A change reviewed as unable to move the numbers (a refactoring with bitwise identical
results) is accepted explicitly, in the JSON, with its reason::

    python benchmarks/_provenance.py --accept benchmarks/results/gp_fit.json --reason "..."

which records the code's digests now and keeps the measurement's commit, with an
``accepted`` entry (commit, date, reason, modules) that the diff shows to the reviewer.
"""

from __future__ import annotations

import datetime
import os
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from rotoruq.evaluation import identity

ROOT = Path(__file__).resolve().parents[1]


def _git(*args: str) -> str:
    done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return done.stdout.strip() if done.returncode == 0 else ""


def _script() -> Path:
    main = sys.modules["__main__"]
    return Path(getattr(main, "__file__", "") or sys.argv[0]).resolve()


def _relative(path: Path) -> str:
    try:
        return path.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return path.as_posix()


def provenance(script: str | Path | None = None, *, modules: Iterable[str] = ()) -> dict:
    """The ``provenance`` block of a benchmark's JSON, computed now (call it when the run
    starts or ends, before the code could change): the git commit, whether the source or the
    script differed from it, the load average (timings on a shared machine), and the digests
    of the rotoruq modules ``script`` (default: the running ``__main__``) imports, plus
    ``modules`` (code a script reaches otherwise, e.g. through a subprocess running the CLI)."""
    path = (ROOT / script).resolve() if script else _script()
    mods = set(identity.script_modules(path)) | set(modules)
    rel = _relative(path)
    dirty = bool(_git("status", "--porcelain", "--", "src", rel))
    return {"commit": _git("rev-parse", "HEAD") or "unknown", "dirty": dirty,
            "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "script": rel, "load": [round(v, 2) for v in os.getloadavg()],
            "modules": identity.module_digests(mods),
            "files": identity.code_parts(mods, every_layer=True)}


def stale(prov: dict | None) -> dict[str, list[str]]:
    """The recorded modules whose code differs now from ``prov``'s, each with the files (or
    epochs) that changed, were added or went; ``{"(no provenance)": []}`` when there is no
    record. Empty: the result measured the code as it is."""
    if not prov or not prov.get("modules"):
        return {"(no provenance)": []}
    now = identity.module_digests(prov["modules"])
    old_files = prov.get("files", {})
    out = {}
    for module, digest in sorted(prov["modules"].items()):
        if now[module] == digest:
            continue
        parts = identity.code_parts([module], every_layer=True)
        changed = [f for f, h in parts.items() if old_files.get(f) != h]
        out[module] = changed or ["(files it no longer imports)"]
    return out


def stale_note(json_path: str | Path) -> str:
    """One line for the docs: empty when ``json_path`` measured the code as it is now, else
    ``stale: measured at <commit> (<date>) before changes to <modules> (<files>)``."""
    import json

    path = ROOT / json_path
    prov = json.loads(path.read_text(encoding="utf-8")).get("provenance")
    changed = stale(prov)
    if not changed:
        return ""
    rel = _relative(path)
    if "(no provenance)" in changed:
        return f"stale: `{rel}` records no provenance (measured before it was recorded)."
    files = sorted({f for fs in changed.values() for f in fs})
    shown = ", ".join(f"`{f}`" for f in files[:8]) + (f" and {len(files) - 8} more"
                                                        if len(files) > 8 else "")
    how = " (reconstructed from git)" if prov.get("reconstructed") else ""
    return (f"stale: `{rel}` was measured at {prov['commit'][:10]} ({prov['date'][:10]}){how} "
            f"before changes to {', '.join(f'`{m}`' for m in changed)} ({shown}); "
            f"re-measure with `{prov['script']}`.")


def reconstruct(json_path: str | Path, script: str | Path, *, modules: Iterable[str] = ()) -> dict:
    """The provenance of a JSON saved before provenance was recorded, from git: the commit
    that last wrote the file, and the digests of the code as it was at that commit (the
    script's imports then, the package's files then). Marked ``"reconstructed": true``."""
    import tarfile
    import tempfile
    from io import BytesIO

    rel = _relative(ROOT / json_path)
    commit = _git("log", "-1", "--format=%H", "--", rel)
    date = _git("log", "-1", "--format=%cI", commit)
    script_rel = _relative(ROOT / script)
    archive = subprocess.run(["git", "archive", commit, "src/rotoruq", script_rel], cwd=ROOT,
                             capture_output=True, check=True).stdout
    saved = identity._PACKAGE
    with tempfile.TemporaryDirectory() as tmp:
        with tarfile.open(fileobj=BytesIO(archive)) as tar:
            tar.extractall(tmp, filter="data")
        try:
            identity._PACKAGE = Path(tmp) / "src" / "rotoruq"
            identity._closure.cache_clear()
            mods = set(identity.script_modules(Path(tmp) / script_rel)) | set(modules)
            digests = identity.module_digests(mods)
            files = identity.code_parts(mods, every_layer=True)
        finally:
            identity._PACKAGE = saved
            identity._closure.cache_clear()
    return {"commit": commit, "dirty": False, "date": date, "script": script_rel,
            "reconstructed": True, "modules": digests, "files": files}


def accept(json_path: str | Path, reason: str) -> dict[str, list[str]]:
    """Accept, after review, the changes :func:`stale` reports for ``json_path``: its
    provenance takes the code's digests now (the measurement's commit and date stay) and an
    ``accepted`` entry with the commit, the date, ``reason`` and the modules. Returns what was
    accepted (empty: nothing was stale)."""
    import json
    import re

    path = ROOT / json_path
    text = path.read_text(encoding="utf-8")
    doc = json.loads(text)
    prov = doc.get("provenance")
    changed = stale(prov)
    if not changed:
        return {}
    if "(no provenance)" in changed:
        raise ValueError(f"{json_path} records no provenance: there is nothing to accept")
    if not reason.strip():
        raise ValueError("an acceptance needs its reason")
    mods = list(prov["modules"])
    prov["modules"] = identity.module_digests(mods)
    prov["files"] = identity.code_parts(mods, every_layer=True)
    prov.setdefault("accepted", []).append({
        "commit": _git("rev-parse", "HEAD") or "unknown",
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "reason": reason, "modules": sorted(changed)})
    m = re.match(r'\{\n( +)"', text)
    path.write_text(json.dumps(doc, indent=len(m.group(1)) if m else 1) + "\n", encoding="utf-8")
    return changed


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="stale saved results; accept a reviewed change")
    ap.add_argument("json", nargs="*", help="saved results (default: every one under "
                    "benchmarks/results and scripts/results)")
    ap.add_argument("--accept", action="store_true", help="accept the changes (needs --reason)")
    ap.add_argument("--reason", default="")
    args = ap.parse_args()
    paths = args.json or sorted(_relative(p) for d in ("benchmarks", "scripts")
                                for p in (ROOT / d / "results").glob("*.json"))
    for j in paths:
        if args.accept:
            print(f"{j}: accepted changes to {', '.join(accept(j, args.reason)) or 'nothing'}")
        elif note := stale_note(j):
            print(note)
