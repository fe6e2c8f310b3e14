"""Every command of the README's "The command line" block runs, in order, in an empty folder
(issue 27: two of them needed files the README never made), so that they cannot rot."""

from __future__ import annotations

import shlex
import subprocess
import sys
import time
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def command_lines() -> list[str]:
    """The commands of the README's "The command line" block, continuation lines joined."""
    section = README.read_text(encoding="utf-8").split("\n## The command line\n", 1)[1]
    block = section.split("```bash\n", 1)[1].split("\n```", 1)[0]
    return [line for line in block.replace("\\\n", " ").splitlines() if line.strip()]


def test_the_readme_block_is_found():
    lines = command_lines()
    assert len(lines) >= 15
    assert all(line.split()[0] in ("tensegrity", "python", "echo") for line in lines), lines


def test_the_readme_command_lines_run_in_order_in_an_empty_folder(tmp_path):
    python = shlex.quote(sys.executable)
    took = []
    for line in command_lines():
        program, rest = line.split(" ", 1)
        command = {"tensegrity": f"{python} -m tensegrity.cli", "python": python}.get(
            program, program
        )
        started = time.perf_counter()
        done = subprocess.run(
            ["bash", "-c", f"{command} {rest}"],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=600,
        )
        took.append((time.perf_counter() - started, line))
        assert done.returncode == 0, f"{line}\n{done.stderr[-3000:]}"
    print("\n".join(f"{seconds:6.1f} s  {line[:80]}" for seconds, line in took))
