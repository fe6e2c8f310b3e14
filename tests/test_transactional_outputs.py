"""Outputs appear all together or not at all (issue 16, docs/reliability.md): a target that is
in the way is found before anything moves, a failed move rolls the folder back to what was
there, what a killed run left behind is removed by the next run, and a run killed with SIGKILL
at any moment leaves every file under a final name either as it was or complete."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree

import pytest
from PIL import Image

from tensegrity.cli.main import main
from tensegrity.io import files
from tensegrity.io.files import remove_stale, write_staged
from tensegrity.io.trajectory import read_trajectory
from tensegrity.plots.viewer import read_viewer_data
from tensegrity.sweep import read_sweep


def _contents(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` by its relative name (hidden ones too)."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def _dead_pid() -> int:
    """The id of a process that has ended."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def _writer(names: dict[str, str]):
    def write(staging: Path) -> list[Path]:
        out = []
        for name, text in names.items():
            path = staging / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            out.append(path)
        return out

    return write


def test_a_folder_where_an_output_goes_changes_nothing(tmp_path, capsys):
    """``matrices`` into a folder of an earlier run where one output's name is now a folder:
    one line naming it, exit code 2, and every file of the earlier run as it was (before, the
    files moved before the failing one had already replaced the old ones)."""
    out = tmp_path / "out"
    assert main(["matrices", "--n", "3", "--m", "1", "--out", str(out)]) == 0
    blocked = sorted(p for p in out.iterdir() if p.suffix == ".npz")[-1]
    blocked.unlink()
    blocked.mkdir()
    before = _contents(out)
    capsys.readouterr()
    assert main(["matrices", "--n", "4", "--m", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and blocked.name in err and "folder" in err, err
    assert _contents(out) == before
    assert not [p for p in out.iterdir() if p.name.startswith(".staging")]


def test_a_failed_move_rolls_the_folder_back(tmp_path, monkeypatch):
    """The third of four moves fails: the two files it replaced are back with their old
    content, the new file is gone, the folder made for it removed, and the error propagates."""
    out = tmp_path / "out"
    write_staged(out, _writer({"a.txt": "old a", "b.txt": "old b", "keep.txt": "kept"}))
    before = _contents(out)
    replace = os.replace
    calls = []

    def failing(source, target):
        if Path(source).parent.name != ".replaced" and Path(target).parent.name != ".replaced":
            calls.append(target)  # a move of a new file into place
            if len(calls) == 3:
                raise OSError(28, "No space left on device")
        return replace(source, target)

    monkeypatch.setattr(files.os, "replace", failing)
    new = {"a.txt": "new a", "sub/c.txt": "new c", "b.txt": "new b", "d.txt": "new d"}
    with pytest.raises(OSError, match="No space"):
        write_staged(out, _writer(new))
    monkeypatch.setattr(files.os, "replace", replace)
    assert len(calls) == 3
    assert _contents(out) == before
    assert not (out / "sub").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".staging")]


def test_outputs_replace_the_old_ones_together(tmp_path):
    out = tmp_path / "out"
    write_staged(out, _writer({"a.txt": "old a", "keep.txt": "kept"}))
    written = write_staged(out, _writer({"a.txt": "new a", "sub/b.txt": "new b"}))
    assert written == [out / "a.txt", out / "sub" / "b.txt"]
    assert _contents(out) == {"a.txt": b"new a", "keep.txt": b"kept", "sub/b.txt": b"new b"}


def _listing(folder: Path, record: str) -> dict:
    return json.loads((folder / f".{record}-outputs").read_text())


def test_outputs_an_earlier_write_listed_and_this_one_does_not_are_removed(tmp_path):
    """With a record, the folder holds one write's outputs: what the earlier write of that
    record listed and this one does not write goes (its emptied folders too); a file the verb
    never wrote, and another record's outputs, stay."""
    out = tmp_path / "out"
    earlier = {"a.txt": "old a", "sub/deeper/b.txt": "b", "c.txt": "c"}
    write_staged(out, _writer(earlier), record="run")
    assert sorted(_listing(out, "run")) == sorted(earlier)
    write_staged(out, _writer({"other.txt": "other's"}), record="other")
    (out / "mine.txt").write_text("the user's")
    written = write_staged(out, _writer({"a.txt": "new a"}), record="run")
    assert written == [out / "a.txt"] and list(_listing(out, "run")) == ["a.txt"]
    assert not (out / "sub").exists()
    assert {k: v for k, v in _contents(out).items() if not k.startswith(".")} == {
        "a.txt": b"new a",
        "mine.txt": b"the user's",
        "other.txt": b"other's",
    }


def test_a_listed_file_changed_since_or_behind_a_link_stays(tmp_path):
    """A listed file the user rewrote, one reached through a symbolic link to another folder,
    and names outside the folder are not removed."""
    out = tmp_path / "out"
    write_staged(out, _writer({"a.txt": "a", "b.txt": "b", "sub/c.txt": "c"}), record="run")
    (out / "a.txt").write_text("the user's own a")
    elsewhere = tmp_path / "elsewhere"
    (out / "sub").rename(elsewhere)
    (out / "sub").symlink_to(elsewhere)
    (tmp_path / "outside.txt").write_text("kept")
    listing = _listing(out, "run")
    listing.update({"../outside.txt": [4, 0], str(tmp_path / "outside.txt"): [4, 0]})
    (out / ".run-outputs").write_text(json.dumps(listing))
    write_staged(out, _writer({"d.txt": "d"}), record="run")
    assert (out / "a.txt").read_text() == "the user's own a" and not (out / "b.txt").exists()
    assert (elsewhere / "c.txt").read_text() == "c" and (tmp_path / "outside.txt").exists()


def test_a_listed_file_that_cannot_be_moved_stays(tmp_path, monkeypatch):
    out = tmp_path / "out"
    write_staged(out, _writer({"a.txt": "a", "b.txt": "b"}), record="run")
    replace = os.replace

    def failing(source, target):
        if Path(source).name == "b.txt" and ".replaced" in Path(target).parts:
            raise OSError(18, "Invalid cross-device link")
        return replace(source, target)

    monkeypatch.setattr(files.os, "replace", failing)
    write_staged(out, _writer({"c.txt": "c"}), record="run")
    assert sorted(p.name for p in out.iterdir()) == [".run-outputs", "b.txt", "c.txt"]


def test_an_interrupted_move_puts_the_superseded_outputs_back(tmp_path, monkeypatch):
    """Interrupted while setting the earlier write's second file aside: the first is back,
    and everything is as before."""
    out = tmp_path / "out"
    write_staged(out, _writer({"a.txt": "old a", "b.txt": "b", "sub/c.txt": "c"}), record="run")
    before = _contents(out)
    replace = os.replace
    aside = []

    def interrupted(source, target):
        if ".replaced" in Path(target).parts and Path(source).name in ("b.txt", "c.txt"):
            aside.append(Path(source).name)
            if len(aside) == 2:
                raise KeyboardInterrupt
        return replace(source, target)

    monkeypatch.setattr(files.os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_staged(out, _writer({"a.txt": "new a"}), record="run")
    monkeypatch.setattr(files.os, "replace", replace)
    assert len(aside) == 2 and _contents(out) == before


def test_simulate_into_an_earlier_runs_folder_leaves_none_of_its_files(tmp_path, capsys):
    """``simulate`` again into the folder of a run with a viewer page and a video, now without
    them: they are gone (before, the earlier run's stayed beside the new one's files, looking
    like its own); a file of the user's stays."""
    out = tmp_path / "out"
    base = ["simulate", "--t-end", "0.2", "--no-steady-state", "--out", str(out)]
    assert main(base) == 0
    assert (out / "view.html").exists() and (out / "motion.gif").exists()
    (out / "notes.txt").write_text("the user's")
    assert main([*base, "--no-view", "--no-animation"]) == 0
    written = capsys.readouterr().out.rsplit("\nwrote ", 1)[1].strip().split(", ")
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == sorted(
        [Path(f).name for f in written] + ["notes.txt"]
    )
    assert not (out / "view.html").exists() and not (out / "motion.gif").exists()


def test_what_a_killed_run_left_is_removed_by_the_next(tmp_path):
    """Staging folders and temporary files of processes that have ended are removed by the next
    write into the folder; those of a live process (another run going on), and names of other
    forms, stay."""
    out = tmp_path / "out"
    out.mkdir()
    dead, live = _dead_pid(), os.getppid()
    (out / f".staging-{dead}-abc").mkdir()
    (out / f".staging-{dead}-abc" / "trajectory.h5").write_text("half")
    (out / f"figure.png.{dead}.x1y2.tmp").write_text("half")
    (out / f".staging-{live}-def").mkdir()
    (out / f"figure.png.{live}.x1y2.tmp").write_text("being written")
    (out / "notes.tmp").write_text("the user's")
    write_staged(out, _writer({"a.txt": "a"}))
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(
        ["a.txt", f".staging-{live}-def", f"figure.png.{live}.x1y2.tmp", "notes.tmp"]
    )
    assert remove_stale(out) == []


def test_atomic_write_removes_its_stale_temporaries(tmp_path):
    dead = _dead_pid()
    stale = tmp_path / f"result.json.{dead}.abcd.tmp"
    other = tmp_path / f"other.json.{dead}.abcd.tmp"
    stale.write_text("{")
    other.write_text("{")
    with files.atomic_path(tmp_path / "result.json") as tmp:
        assert f".{os.getpid()}." in tmp.name
        tmp.write_text("{}")
    assert not stale.exists() and other.exists()  # only the file being written is tidied


#: An analysis verb's quick options, and the computations (module, function) it runs, each
#: looked up where the verb finds it when it runs.
ANALYSIS_COMPUTATIONS = {
    "equilibrium": (
        ["--method", "least_squares"],
        [("tensegrity.cli.analysis", "find_equilibrium")],
    ),
    "modes": (
        [],
        [
            ("tensegrity.cli.analysis", "find_equilibrium"),
            ("tensegrity.analysis.modes", "modal_analysis"),
        ],
    ),
    "controllability": (
        ["--inputs", "all"],
        [
            ("tensegrity.cli.analysis", "find_equilibrium"),
            ("tensegrity.analysis.controllability", "controllability_table"),
        ],
    ),
    "control": (
        ["--steps", "1", "1", "--no-closed-loop"],
        [
            ("tensegrity.cli.analysis", "find_equilibrium"),
            ("tensegrity.analysis.shape_control", "quasi_static"),
        ],
    ),
}


@pytest.mark.parametrize("verb", ANALYSIS_COMPUTATIONS)
def test_analysis_verbs_compute_outside_the_output_folder(tmp_path, monkeypatch, capsys, verb):
    """The analysis verbs compute first, with nothing of theirs in ``--out``, and stage only the
    writing of their files: a run killed while it computes (most of its time) leaves no staging
    folder (before, the whole computation ran inside one)."""
    import importlib

    out = tmp_path / "out"
    options, computations = ANALYSIS_COMPUTATIONS[verb]
    seen: list[tuple[str, list[str]]] = []

    def watched(name, function):
        def compute(*args, **kwargs):
            inside = [p.name for p in out.rglob("*")] if out.exists() else []
            seen.append((name, inside))
            return function(*args, **kwargs)

        return compute

    for module_name, name in computations:
        module = importlib.import_module(module_name)
        monkeypatch.setattr(module, name, watched(name, getattr(module, name)))
    assert main([verb, *options, "--out", str(out)]) == 0
    assert {name for name, _ in seen} == {name for _, name in computations}
    assert all(inside == [] for _, inside in seen), seen
    written = capsys.readouterr().out.rsplit("\nwrote ", 1)[1].strip().split(", ")
    listing = f".{verb}-outputs"  # (write_staged's record of them)
    assert sorted(p.name for p in out.iterdir() if p.name != listing) == sorted(
        Path(f).name for f in written
    )
    assert list(json.loads((out / listing).read_text())) == [Path(f).name for f in written]


def _check_complete(path: Path, content: bytes) -> None:
    """``AssertionError`` unless ``path`` is a complete output file of its kind."""
    if path.suffix == ".h5":
        read_trajectory(path)
    elif path.suffix == ".json":
        json.loads(content)
    elif path.suffix == ".png":
        assert content.startswith(b"\x89PNG") and content.endswith(b"IEND\xaeB`\x82"), path
    elif path.suffix in (".vtp", ".pvd"):
        ElementTree.fromstring(content)
    elif path.suffix == ".nc":
        assert read_sweep(path).sizes["case"] == 8, path
    elif path.suffix == ".gif":  # (the trailer ends the file; every frame decodes)
        assert content.startswith(b"GIF89a") and content.endswith(b"\x3b"), path
        with Image.open(io.BytesIO(content)) as gif:
            for k in range(gif.n_frames):
                gif.seek(k)
                gif.load()
    elif path.suffix == ".html":
        text = content.decode("utf-8")
        assert text.rstrip().endswith("</html>"), path
        assert read_viewer_data(text)["n_frames"] >= 2, path
    else:
        raise AssertionError(f"unexpected file {path}")


def _verb(name: str, tmp_path: Path) -> tuple[list[str], list[str]]:
    """The arguments of a verb's earlier run and of the run to kill (a different result)."""
    if name == "simulate":
        return (
            ["--t-end", "0.5", "--no-steady-state"],
            ["--n", "4", "--m", "2", "--t-end", "2", "--no-steady-state"],
        )
    if name == "equilibrium":
        return ["--n", "3", "--m", "1"], ["--n", "4", "--m", "2"]
    if name == "sweep":  # (the output is one file, inside --out's folder here)
        return (
            ["--param", "stiffness=100,200", "--t-end", "0.01", "--workers", "1"],
            ["--param", "stiffness=100,150,200,250", "--param", "n=3,4", "--t-end", "0.2"],
        )
    runs = []
    for n, m, t_end in (("3", "1", "0.2"), ("5", "3", "3")):  # vtk: two trajectories
        folder = tmp_path / f"run{n}{m}"
        main(["simulate", "--n", n, "--m", m, "--t-end", t_end, "--no-steady-state",
              "--sample-dt", "0.002", "--out", str(folder)])  # fmt: skip
        runs.append([str(folder / "trajectory.h5")])
    return runs[0], runs[1]


KILL_AFTER = {
    "simulate": [0.4, 0.9, 1.3, 1.8, 2.4],  # seconds: imports, the run, the figures, the moves
    "equilibrium": [0.6, 1.2, 1.7],
    "vtk": [0.5, 1.0, 1.5],
    "sweep": [1.0, 2.5, 4.0],  # (the cluster starts, the cases run, the file is written)
}


@pytest.mark.parametrize(
    "verb, delay", [(verb, delay) for verb, delays in KILL_AFTER.items() for delay in delays]
)
def test_a_verb_killed_at_any_moment_leaves_each_file_old_or_complete(tmp_path, verb, delay):
    """``tensegrity VERB`` into the folder of an earlier run, killed with SIGKILL after
    ``delay``: every file under a final name is the earlier run's, byte for byte, or a complete
    file of the new run (a trajectory that reads, JSON that parses, a PNG with its end chunk,
    VTK XML that parses); the next run removes what the killed one left and leaves no staging
    folder or temporary file behind."""
    out = tmp_path / "out"
    old_args, new_args = _verb(verb, tmp_path)
    base = [sys.executable, "-m", "tensegrity.cli", verb]
    where = {"vtk": ["--output", str(out)], "sweep": ["-o", str(out / "sweep.nc")]}.get(
        verb, ["--out", str(out)]
    )
    out.mkdir()  # (sweep writes one file into a folder that must exist)
    subprocess.run([*base, *old_args, *where], check=True, capture_output=True)
    old = _contents(out)
    child = subprocess.Popen(
        [*base, *new_args, *where], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    time.sleep(delay)
    child.send_signal(signal.SIGKILL)
    child.wait()
    for name, content in _contents(out).items():
        if any(part.startswith(".") for part in Path(name).parts):
            continue  # a hidden staging folder, partial or temporary file
        if old.get(name) != content:
            _check_complete(out / name, content)
    subprocess.run([*base, *old_args, *where], check=True, capture_output=True)
    left = [p for p in out.rglob("*") if p.name.startswith(".staging") or ".tmp" in p.name]
    assert left == []
    assert _contents(out).keys() >= old.keys()


SIMULATE = ["simulate", "--t-end", "0.5", "--no-steady-state", "--no-view", "--no-animation"]


@pytest.mark.parametrize(
    "obstacle, extra",
    [("trajectory.h5", []), ("equilibrium.png", []), ("vtk/tensegrity.pvd", ["--vtk"])],
)
def test_simulate_refuses_an_output_obstacle_before_the_run(
    tmp_path, capsys, monkeypatch, obstacle, extra
):
    """A folder where one of ``simulate``'s files goes is refused at once: no run, no partial
    file (before, the run went to its end and then said 'nothing was written')."""
    import tensegrity.io.stream

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(tensegrity.io.stream, "simulate_to_file", no_run)
    out = tmp_path / "out"
    (out / obstacle).mkdir(parents=True)
    assert main([*SIMULATE, *extra, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out: {out / obstacle}: is a folder" in err, err
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == sorted(
        {obstacle, *[str(p.as_posix()) for p in Path(obstacle).parents if str(p) != "."]}
    )


def test_an_obstacle_found_after_the_run_names_the_kept_run_and_resume(
    tmp_path, capsys, monkeypatch
):
    """An obstacle that appears while the run goes on: the finished run is kept, and the line
    says where and names --resume, which then writes the files without running again."""
    import tensegrity.io.stream

    out = tmp_path / "out"
    run = tensegrity.io.stream.simulate_to_file

    def run_then_block(*args, **kwargs):
        summary = run(*args, **kwargs)
        (out / "structure.json").mkdir()  # after the check, before the files are written
        return summary

    monkeypatch.setattr(tensegrity.io.stream, "simulate_to_file", run_then_block)
    assert main([*SIMULATE, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    kept = out / ".trajectory.h5"
    assert err.count("\n") == 1 and f"{out / 'structure.json'}: is a folder" in err, err
    assert f"the run so far is in {kept}" in err and "--resume" in err, err
    assert "nothing was written" not in err and kept.exists()
    monkeypatch.setattr(tensegrity.io.stream, "simulate_to_file", run)
    (out / "structure.json").rmdir()
    assert main([*SIMULATE, "--out", str(out), "--resume"]) == 0
    assert (out / "trajectory.h5").exists() and not kept.exists()
