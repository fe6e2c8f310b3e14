"""The front door cannot rot: every command of ``docs/cli.md``'s session runs, in order, in an
empty folder (issue 27: two of them needed files the docs never made); the README's short tour
(its Python block and its shell block) runs; the README stays a few screens long, without the
clock times of benchmark prose (issue 33), and its quick start is the two commands."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
CLI_PAGE = ROOT / "docs" / "cli.md"

#: The README's largest size [bytes] (issue 33: "about 10 kB at most").
README_LIMIT = 10_000


def blocks(path: Path, language: str) -> list[str]:
    """The fenced ``language`` blocks of the markdown file ``path``, in order."""
    return re.findall(rf"```{language}\n(.*?)\n```", path.read_text(encoding="utf-8"), re.S)


def command_lines(block: str) -> list[str]:
    """The commands of a shell ``block``, continuation lines joined."""
    return [line for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def run_in_order(lines: list[str], folder: Path) -> None:
    """Each command line in ``folder``, in order (``tensegrity`` as this interpreter's module),
    each to succeed."""
    python = shlex.quote(sys.executable)
    took = []
    for line in lines:
        program, rest = line.split(" ", 1)
        command = {"tensegrity": f"{python} -m tensegrity.cli", "python": python}.get(
            program, program
        )
        started = time.perf_counter()
        done = subprocess.run(
            ["bash", "-c", f"{command} {rest}"],
            cwd=folder,
            capture_output=True,
            text=True,
            timeout=600,
        )
        took.append((time.perf_counter() - started, line))
        assert done.returncode == 0, f"{line}\n{done.stderr[-3000:]}"
    print("\n".join(f"{seconds:6.1f} s  {line[:80]}" for seconds, line in took))


def test_the_cli_page_block_is_found():
    lines = command_lines(blocks(CLI_PAGE, "bash")[0])
    assert len(lines) >= 15
    assert all(line.split()[0] in ("tensegrity", "python", "echo") for line in lines), lines


def test_the_cli_pages_command_lines_run_in_order_in_an_empty_folder(tmp_path):
    run_in_order(command_lines(blocks(CLI_PAGE, "bash")[0]), tmp_path)


def test_the_readmes_tour_runs(tmp_path):
    """The Python block, then the shell block, in an empty folder."""
    (python,) = blocks(README, "python")
    said = "\nprint(run.message, f'{modal_analysis(linearize(shell, eq)).frequency_hz[6]:.3f}')"
    done = subprocess.run(
        [sys.executable, "-c", python + said],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["steady", "state", "at", "t", "=", "4.04", "s", "2.129"]
    assert "'steady state at t = 4.04 s'" in python and "2.129 Hz" in python  # (as it says)
    quick_start, tour = blocks(README, "bash")
    assert command_lines(quick_start) == [
        "pip install . && tensegrity simulate",
        "pip install '.[test]' && pytest",
    ]
    run_in_order(command_lines(tour), tmp_path)


def test_ci_runs_both_quick_start_commands_in_its_fresh_environment():
    """``.ci/run`` runs the first command before any extra is installed (its results in a
    scratch folder) and the second verbatim, last."""
    first, second = command_lines(blocks(README, "bash")[0])
    install, main_job = first.split(" && ")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    runs = [line for line in ci if line.strip() and not line.lstrip().startswith("#")]
    first_run = next(k for k, line in enumerate(runs) if main_job in line)
    # (the install on its own line: under ``set -e`` a failure ends CI, as it would not in an
    # ``&&`` list)
    assert runs[first_run - 1] == install.replace("pip install", "pip install --quiet")
    assert not any(".[" in line for line in runs[:first_run])  # (no extra installed before it)
    assert runs[runs.index("status=$?") - 1] == second  # (its exit status is CI's)


def test_the_readme_is_short_and_has_no_clock_times():
    text = README.read_text(encoding="utf-8")
    assert len(text.encode()) <= README_LIMIT
    times = re.findall(r"(?<![\d.])(?<!t = )\d+(?:\.\d+)? ?(?:ms|s|min|minutes|seconds)\b", text)
    assert not times, times
    assert not re.findall(r"\b\d{1,2}:\d{2}\b|\b20\d\d-\d\d-\d\d\b", text)
    for link in re.findall(r"\]\(([^)#:]+)\)", text):  # every relative link leads to a file
        assert (ROOT / link).exists(), link
