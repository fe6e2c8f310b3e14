"""What a video costs: ``tensegrity.plots.animation.animate`` on the (3,1) example and the
(30,30) shell, and a frame drawn over the kept background (what ``animate`` does) against the
whole figure drawn for each frame (what it did before), side by side in one run.

Usage::

    python benchmarks/bench_animation.py [--quick]

Prints a Markdown table: per case the frames, the seconds of ``animate`` (drawing and encoding,
800x640 pixels), the file size, and the milliseconds a frame of each way of drawing (no
encoding) with their ratio.  ``--quick``: the (3,1) cases only.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from tensegrity import class1_shell, critical_damping, simulate
from tensegrity.plots.animation import _Scene, animate
from tensegrity.plots.motion import frame_indices, make_frames, playback_times

SIZE = (800, 640)


def _per_frame(run, fps: float, duration: float) -> tuple[float, float]:
    """Milliseconds a frame: drawn over the kept background, and the whole figure drawn."""
    times = playback_times(run.t[0], run.t[-1], fps=fps, duration=duration)
    frames = make_frames(run, frame_indices(run.t, times))
    scene = _Scene(frames, size=SIZE, view=None)
    start = time.perf_counter()
    for k in range(frames.n_frames):
        scene.show(k)
    blitted = (time.perf_counter() - start) / frames.n_frames
    for artist in scene.moving:
        artist.set_animated(False)
    start = time.perf_counter()
    for k in range(frames.n_frames):
        scene.show(k)  # (the frame's artists set; then the whole figure drawn)
        scene.figure.canvas.draw()
        scene.labelled(k)
    whole = (time.perf_counter() - start) / frames.n_frames
    return 1e3 * blitted, 1e3 * whole


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the (3,1) cases only")
    quick = parser.parse_args().quick
    small = simulate(critical_damping(class1_shell(3, 1)), (0.0, 10.0), sample_dt=0.01)
    cases = [
        ("(3,1) shell, 10 s at 30 fps, MP4", small, ".mp4", 10.0),
        ("(3,1) shell, 10 s at 30 fps, WebM", small, ".webm", 10.0),
        ("(3,1) shell, 3 s at 30 fps, GIF", small, ".gif", 3.0),
    ]
    if not quick:
        big = simulate(critical_damping(class1_shell(30, 30)), (0.0, 0.2), sample_dt=0.01)
        cases.append(("(30,30) shell, 2 s at 30 fps, MP4", big, ".mp4", 2.0))
    print("| what | frames | animate | file | ms a frame: blitted | whole figure | ratio |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name, run, suffix, duration in cases:
            path = Path(folder) / f"motion{suffix}"
            start = time.perf_counter()
            animate(run, path, fps=30.0, duration=duration, progress=False)
            seconds = time.perf_counter() - start
            blitted, whole = _per_frame(run, 30.0, duration)
            n_frames = int(np.round(30.0 * duration))
            print(
                f"| {name} | {n_frames} | {seconds:.2f} s | {path.stat().st_size / 1e6:.2f} MB "
                f"| {blitted:.1f} | {whole:.1f} | {blitted / whole:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
