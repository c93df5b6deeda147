"""A study file or a results folder from someone else cannot hurt you (issue 27, the file
system and terminal part).

Through the command line, in a temporary root listed before and after: a results folder whose
lock file, ``steps/``, ``report/``, ``work/``, store or step folder is a symlink is refused
with a message naming it, and nothing anywhere in the root changes (the victim files keep
their bytes); tampered step files give one line "not written by rotoruq: FILE" and never run
a pickle; files and folders of a run follow the umask; error messages carry no escape codes.
The validators of names and paths are checked on generated names (hypothesis).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _inproc import rotoruq
from rotoruq.errors import InputFileError
from rotoruq.results import StepResult, load_step, save_step, save_study_info
from rotoruq.safety import (
    UnsafePathError,
    check_name,
    check_relative,
    inside,
    is_control,
    name_problem,
    terminal_text,
)
from rotoruq.study.lock import LOCK_NAME, results_lock
from rotoruq.study.paths import check_study_paths
from rotoruq.study.schema import parse_study

CLI = [sys.executable, "-m", "rotoruq.study.cli"]

DRIVER = r'''
import sys
vals = {k.strip(): float(v) for k, v in (line.split("=") for line in open("input.txt"))}
a, b = vals["a"], vals["b"]
open(sys.argv[2], "w").write(f"{2 * a + b!r} y1\n")
'''

STUDY = """\
[study]
name = "ext"
seed = 3

[model]
command = [{python}, "-S", "driver.py", "{{params}}", "{{results}}"]
templates = ["input.txt"]
responses = ["y1"]

[parameters.a]
distribution = "uniform"
lower = 0.0
upper = 1.0

[parameters.b]
distribution = "normal"
mean = 2.0
std = 0.5

[[steps]]
name = "lhs"
type = "sampling"
n_samples = 3
"""


def make_study(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "driver.py").write_text(DRIVER)
    (folder / "input.txt").write_text("a = {a}\nb = {b}\n")
    path = folder / "study.toml"
    path.write_text(STUDY.format(python=json.dumps(sys.executable)))
    return path


def cli(*args, umask: int = -1, timeout: float = 120) -> subprocess.CompletedProcess:
    """``rotoruq ARGS``: with a ``umask``, in a fresh process started with it; otherwise
    through the CLI's entry point in this process (``tests/_inproc.py``: what is checked is
    what the command writes, refuses and says, not the process)."""
    if umask == -1:
        return rotoruq(*args)
    return subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, umask=umask)


def snapshot(root: Path) -> dict[str, tuple]:
    """Every entry under ``root`` (links not followed): kind, mode and content digest."""
    out: dict[str, tuple] = {}
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        for n in dirnames + filenames:
            p = Path(dirpath) / n
            st_ = os.lstat(p)
            if stat.S_ISLNK(st_.st_mode):
                out[str(p.relative_to(root))] = ("link", os.readlink(p))
            elif stat.S_ISREG(st_.st_mode):
                out[str(p.relative_to(root))] = ("file", st_.st_mode,
                                                 hashlib.sha256(p.read_bytes()).hexdigest())
            else:
                out[str(p.relative_to(root))] = ("dir", st_.st_mode)
    return out


@pytest.fixture
def root(tmp_path: Path) -> Path:
    """A study, an empty results folder ``out`` and a victim folder beside them."""
    make_study(tmp_path / "st")
    (tmp_path / "out").mkdir()
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "precious.txt").write_text("precious bytes\n")
    return tmp_path


def refused_without_writes(root: Path, *args, expect: list[str]) -> str:
    """Run the CLI; it must fail (code 1, no internal error) with every ``expect`` in its
    message and change nothing in ``root`` but create the results folder's own lock file."""
    before = snapshot(root)
    proc = cli(*args)
    after = snapshot(root)
    after.pop(os.path.join("out", LOCK_NAME), None)
    before.pop(os.path.join("out", LOCK_NAME), None)
    assert proc.returncode == 1, proc.stderr
    assert "internal error" not in proc.stderr
    for word in expect:
        assert word in proc.stderr, proc.stderr
    assert after == before
    assert (root / "victim" / "precious.txt").read_text() == "precious bytes\n"
    return proc.stderr


def test_a_symlinked_lock_file_is_refused_and_its_target_kept(root):
    (root / "out" / LOCK_NAME).symlink_to(root / "victim" / "precious.txt")
    refused_without_writes(root, "run", root / "st" / "study.toml", "--out", root / "out",
                           "--no-report", expect=["symlink in a results folder", LOCK_NAME])


def test_a_lock_file_linked_to_a_missing_file_creates_nothing(root):
    (root / "out" / LOCK_NAME).symlink_to(root / "victim" / "new.txt")
    refused_without_writes(root, "run", root / "st" / "study.toml", "--out", root / "out",
                           "--no-report", expect=["symlink in a results folder", LOCK_NAME])
    assert not (root / "victim" / "new.txt").exists()


@pytest.mark.parametrize("how", ["hard link", "foreign bytes"])
def test_a_lock_file_rotoruq_did_not_write_is_never_truncated(root, how):
    lock = root / "out" / LOCK_NAME
    if how == "hard link":
        os.link(root / "victim" / "precious.txt", lock)
    else:
        lock.write_text("someone's notes\n")
    before = lock.read_bytes()
    refused_without_writes(root, "run", root / "st" / "study.toml", "--out", root / "out",
                           "--no-report", expect=["not written by rotoruq", LOCK_NAME])
    assert lock.read_bytes() == before


@pytest.mark.parametrize("entry", ["steps", "report", "work", "steps/lhs", "study.json",
                                   "evaluations.sqlite"])
def test_a_symlink_in_the_results_folder_is_refused_naming_it(root, entry):
    """A results folder unpacked from an archive (tar keeps links) and run again."""
    if entry.startswith("steps/"):
        (root / "out" / "steps").mkdir()
    target = root / "victim" / ("missing.sqlite" if entry == "evaluations.sqlite" else "")
    (root / "out" / entry).symlink_to(target if entry == "evaluations.sqlite"
                                      else root / "victim")
    # the store is refused already where the study names it (its path leads outside the
    # results folder through the link); the other entries by the results-folder check
    expect = (["[store] path", "through a symlink"] if entry == "evaluations.sqlite" else
              ["symlink in a results folder", str(root / "out" / entry)])
    err = refused_without_writes(root, "run", root / "st" / "study.toml", "--out",
                                 root / "out", expect=expect)
    assert err.count("\n") == 1  # one line
    assert sorted(p.name for p in (root / "victim").iterdir()) == ["precious.txt"]


def test_a_run_follows_the_umask_and_its_results_read_back(tmp_path):
    for umask in (0o027, 0o002):
        out = tmp_path / f"out{umask:o}"
        proc = cli("run", make_study(tmp_path / "st"), "--out", out, "--no-report",
                   umask=umask)
        assert proc.returncode == 0, proc.stderr
        step = out / "steps" / "lhs"
        for f in [out / "study.json", out / "study.toml", out / LOCK_NAME, *step.iterdir()]:
            assert stat.S_IMODE(f.stat().st_mode) == 0o666 & ~umask, f
        # SQLite makes its database 0644 less the umask (its SQLITE_DEFAULT_FILE_PERMISSIONS)
        assert stat.S_IMODE((out / "evaluations.sqlite").stat().st_mode) == 0o644 & ~umask
        for d in (out / "steps", step):
            assert stat.S_IMODE(d.stat().st_mode) == 0o777 & ~umask, d
        assert load_step(step).arrays["outputs"].shape == (3, 1)


# --- tampered results: `show` names the file, never an internal error, never unpickles ---

class _Marker:
    """Unpickling it would create the file ``path``."""

    def __init__(self, path: str):
        self.path = path

    def __reduce__(self):
        return (open, (self.path, "w"))


def saved_folder(out: Path) -> Path:
    save_step(StepResult("lhs", "sampling", {"mean/y1": 1.0},
                         {"inputs": np.arange(6.0).reshape(3, 2)},
                         meta={"columns": {"inputs": ["a", "b"]}}), out)
    save_study_info(out, {"name": "ext", "steps": ["lhs"]})
    return out / "steps" / "lhs"


def rewrite(step: Path, edit) -> None:
    doc = json.loads((step / "result.json").read_text())
    edit(doc)
    (step / "result.json").write_text(json.dumps(doc))


def test_a_pickled_array_is_not_written_by_rotoruq_and_never_unpickled(tmp_path):
    step = saved_folder(tmp_path / "out")
    marker = tmp_path / "unpickled"
    np.save(step / "inputs.npy", np.array([_Marker(str(marker))], dtype=object),
            allow_pickle=True)
    np.load(step / "inputs.npy", allow_pickle=True)  # the payload works: it makes the marker
    assert marker.exists()
    marker.unlink()
    sha = hashlib.sha256((step / "inputs.npy").read_bytes()).hexdigest()
    rewrite(step, lambda d: d["files"].update({"inputs.npy": sha}))
    proc = cli("show", tmp_path / "out")
    assert proc.returncode == 1
    assert proc.stderr.strip() == (
        f"rotoruq show: error: not written by rotoruq: {step / 'inputs.npy'} (not a plain "
        "numpy array: Object arrays cannot be loaded when allow_pickle=False); remove it or "
        "re-run the step")
    assert not marker.exists()


@pytest.mark.parametrize("field,value", [
    ("arrays", ["../../../study"]),
    ("files", {"../../../study.json": "0" * 64}),
    ("files", {"/etc/hostname": "0" * 64}),
    ("scalars", ["not", "a", "table"]),
    ("name", "other"),
    ("meta", {"seconds": "x"}),
    ("meta", {"columns": {"inputs": 5}}),
    ("meta", {"record": 5}),
])
def test_a_result_json_pointing_outside_its_folder_is_refused(tmp_path, field, value):
    step = saved_folder(tmp_path / "out")
    rewrite(step, lambda d: d.update({field: value}))
    proc = cli("show", tmp_path / "out")
    assert proc.returncode == 1, proc.stdout
    assert proc.stderr.startswith(f"rotoruq show: error: not written by rotoruq: "
                                  f"{step / 'result.json'} (")
    assert proc.stderr.rstrip().endswith("remove it or re-run the step")
    assert proc.stderr.count("\n") == 1


def test_a_record_of_a_known_type_without_its_fields_is_shown_flat_with_why(tmp_path):
    save_step(StepResult("sobol", "sensitivity", {"S/y1/a": 0.5},
                         meta={"record": {"type": "SensitivityRecord", "version": 1,
                                          "fields": {}}}), tmp_path / "out")
    save_study_info(tmp_path / "out", {"name": "ext", "steps": ["sobol"]})
    proc = cli("show", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    assert "not written by rotoruq: step 'sobol' (its SensitivityRecord lacks" in proc.stdout


@pytest.mark.parametrize("entry", ["study.json", "steps/lhs", "steps/lhs/inputs.npy"])
def test_show_refuses_a_symlink_in_the_results_folder(tmp_path, entry):
    step = saved_folder(tmp_path / "out")
    victim = tmp_path / "victim"
    victim.mkdir()
    target = tmp_path / "out" / entry
    os.replace(target, victim / target.name)
    target.symlink_to(victim / target.name)
    proc = cli("show", tmp_path / "out")
    assert proc.returncode == 1
    assert f"symlink in a results folder: {target} ->" in proc.stderr, proc.stderr
    assert step.parent.is_dir()


def test_error_messages_carry_no_escape_codes(tmp_path):
    evil = tmp_path / "out\x1b]0;owned\x07\x1b[2J\u202e"
    step = saved_folder(evil)
    rewrite(step, lambda d: d.update(name="lhs\x1b[8m"))
    proc = cli("show", evil)
    assert proc.returncode == 1
    assert not any(is_control(c) for c in proc.stderr.rstrip("\n")), repr(proc.stderr)
    assert "\\x1b]0;owned\\x07\\x1b[2J\\u202e" in proc.stderr


# --- the validators, directly ---

def test_save_step_refuses_a_name_that_leaves_its_folder(tmp_path):
    for name in ("../escaped", "a/b", ".hidden", "x\x1by", ""):
        with pytest.raises(InputFileError, match="a step name without"):
            save_step(StepResult(name, "sampling", {"m": 1.0}), tmp_path / "out")
    assert sorted(tmp_path.iterdir()) == []


def test_the_lock_refuses_a_planted_steps_link_before_any_write(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "elsewhere").mkdir()
    (out / "steps").symlink_to(tmp_path / "elsewhere")
    with pytest.raises(UnsafePathError, match=r"symlink in a results folder: .*steps ->"):
        with results_lock(out):
            pass
    assert (out / LOCK_NAME).read_bytes() == b""
    with pytest.raises(UnsafePathError, match="symlink in a results folder"):
        save_step(StepResult("lhs", "sampling", {"m": 1.0}), out)
    assert list((tmp_path / "elsewhere").iterdir()) == []


def study_text(**lines: str) -> str:
    """The external study with some lines replaced or added (key: a TOML line)."""
    text = STUDY.format(python='"python"')
    for key, line in lines.items():
        if key == "name":
            text = text.replace('name = "ext"', line)
        elif key == "step":
            text = text.replace('name = "lhs"', line)
        else:
            text = text.replace("[model]\n", f"[model]\n{line}\n") if key == "model" else \
                text.replace("[[steps]]", f"{line}\n\n[[steps]]")
    return text


@pytest.mark.parametrize("lines,expected", [
    ({"name": 'name = "../../../escaped"'}, "the study name without"),
    ({"name": 'name = "x\\u001b]0;t\\u0007"'}, "the study name without"),
    ({"name": 'name = "a"\noutput = "../../elsewhere"'}, "[study] output relative"),
    ({"name": 'name = "a"\noutput = "/tmp/elsewhere"'}, "[study] output relative"),
    ({"other": '[store]\npath = "../../store.sqlite"'}, "[store] path (or allow"),
    ({"other": '[store]\npath = "/tmp/store.sqlite"'}, "[store] path (or allow"),
    ({"model": 'workdir = "../../work"'}, "[model] workdir relative"),
    ({"model": 'files = ["/etc/passwd"]'}, "a [model] files entry relative"),
    ({"model": 'templates = ["../input.txt"]'}, "a [model] templates entry relative"),
    ({"other": '[data.m]\nfile = "../measured.csv"'}, "[data.m] file relative"),
])
def test_study_paths_that_leave_their_folder_are_refused_naming_the_line(
        tmp_path, lines, expected):
    path = tmp_path / "st" / "study.toml"
    make_study(tmp_path / "st")
    (tmp_path / "measured.csv").write_text("y1\n1.0\n")  # exists: only its place is wrong
    (tmp_path / "input.txt").write_text("a = {a}\n")
    text = study_text(**lines)
    if "templates" in str(lines):
        text = text.replace('templates = ["input.txt"]\n', "")
    line_no = text.splitlines().index(next(iter(lines.values())).splitlines()[-1]) + 1
    with pytest.raises(InputFileError) as exc:  # names already where the file is parsed
        check_study_paths(parse_study(text, path), tmp_path / "out")
    assert exc.value.line == line_no, str(exc.value)
    assert expected in str(exc.value)
    assert not any(is_control(c) for c in str(exc.value))
    check_study_paths(parse_study(study_text(), path), tmp_path / "out")  # the study is fine


def test_an_outside_store_is_allowed_only_when_asked(tmp_path):
    study = parse_study(study_text(other='[store]\npath = "/tmp/shared.sqlite"'),
                        tmp_path / "study.toml")
    check_study_paths(study, tmp_path / "out", outside_store=True)
    with pytest.raises(InputFileError, match=r"\[store\] path"):
        check_study_paths(study, tmp_path / "out")


def test_a_store_reached_through_a_planted_link_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (tmp_path / "elsewhere").mkdir()
    (out / "db").symlink_to(tmp_path / "elsewhere")
    study = parse_study(study_text(other='[store]\npath = "db/e.sqlite"'),
                        tmp_path / "study.toml")
    with pytest.raises(InputFileError, match="through a symlink"):
        check_study_paths(study, out)
    assert inside(out, "e.sqlite") == out / "e.sqlite"


_TEXT = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=30)
_CONTROL = st.text(st.sampled_from("\x00\x07\x1b\x7f\x85\x9b\u202e\u2066\n\t"), min_size=1,
                   max_size=3)


@settings(max_examples=300, deadline=None)
@given(_TEXT, _CONTROL, _TEXT)
def test_terminal_text_leaves_no_control_character(head, control, tail):
    s = head + control + tail
    shown = terminal_text(s)
    assert not any(is_control(c) for c in shown)
    assert all(f"\\x{ord(c):02x}" in shown or f"\\u{ord(c):04x}" in shown for c in control)
    clean = "".join(c for c in head + tail if not is_control(c))
    assert terminal_text(clean) == clean  # printable text is left as it is
    kept = terminal_text(s, lines=True)
    assert not any(is_control(c) and c not in "\n\t" for c in kept)


@settings(max_examples=300, deadline=None)
@given(st.one_of(_TEXT, st.builds(lambda a, c, b: a + c + b, _TEXT, _CONTROL, _TEXT)))
def test_names_are_accepted_exactly_when_they_name_one_plain_file(name):
    plain = (name.strip() != "" and not any(is_control(c) for c in name)
             and "/" not in name and "\\" not in name and ".." not in name
             and not name.startswith(".") and len(name.encode()) <= 200)
    assert (name_problem(name) is None) == plain
    if plain:
        assert check_name(name) == name
        assert Path(name).name == name and len(Path(name).parts) == 1
    else:
        with pytest.raises(InputFileError) as exc:
            check_name(name, what="the study name", path="s.toml", line=2)
        assert not any(is_control(c) for c in str(exc.value))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(["a", "b.txt", "..", ".", "", "x\x1b", "/", "~"]),
                min_size=1, max_size=5))
def test_relative_paths_never_climb_out(parts):
    text = "/".join(parts)
    try:
        rel = check_relative(text)
    except InputFileError as exc:
        assert not any(is_control(c) for c in str(exc))
        return
    assert not rel.is_absolute() and ".." not in rel.parts
    base = Path("/base/folder")
    assert base in (base / rel).parents or base / rel == base


@pytest.mark.parametrize("old,new,expect", [
    ('name = "ext"', 'name = "../../../escaped"', "line 2: expected the study name without"),
    ('name = "ext"', 'name = "x\\u001b]0;owned\\u0007"', "line 2: expected the study name"),
    ('name = "ext"', 'name = "ext"\noutput = "../../escaped"',
     "line 3: expected [study] output relative"),
    ("[[steps]]", '[store]\npath = "../../store.sqlite"\n[[steps]]',
     "line 21: expected [store] path"),
    ("[[steps]]", '[store]\npath = "/tmp/store.sqlite"\n[[steps]]',
     "line 21: expected [store] path"),
])
def test_a_study_naming_a_place_outside_is_refused_before_any_write(root, old, new, expect):
    study = root / "st" / "study.toml"
    study.write_text(study.read_text().replace(old, new))
    before = snapshot(root)
    proc = cli("run", study, "--no-report")
    assert proc.returncode == 1, proc.stderr
    assert expect in proc.stderr and "\x1b" not in proc.stderr, proc.stderr
    assert snapshot(root) == before


def test_an_outside_store_is_written_only_with_the_option(root):
    study = root / "st" / "study.toml"
    store = root / "shared" / "store.sqlite"
    store.parent.mkdir()
    study.write_text(study.read_text().replace(
        '[[steps]]', f'[store]\npath = "{store}"\n\n[[steps]]'))
    assert cli("run", study, "--out", root / "out", "--no-report").returncode == 1
    assert not store.exists()
    proc = cli("run", study, "--out", root / "out", "--no-report", "--allow-outside-store")
    assert proc.returncode == 0, proc.stderr
    assert store.is_file()
