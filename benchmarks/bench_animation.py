"""What a video costs: ``tensegrity.plots.animation.animate`` on the (3,1) example and the
(30,30) shell (and the GIF ``tensegrity simulate`` draws by default), and a frame drawn over
the kept background (what ``animate`` does) against the whole figure drawn for each frame (what
it did before), side by side in one run.

Usage::

    python benchmarks/bench_animation.py [--quick]

Prints a Markdown table: per case the frames, the seconds of ``animate`` (drawing and encoding,
800x640 pixels unless said), the file size, and the milliseconds a frame of each way of drawing
(no encoding) with their ratio.  ``--quick``: the (3,1) cases only.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.cli.simulate_files import VIDEO_FPS, VIDEO_SIZE
from tensegrity.plots.animation import _Scene, animate
from tensegrity.plots.motion import frame_indices, frame_rate, make_frames, playback_times

SIZE = (800, 640)


def _per_frame(run, fps: float, duration: float | None, size) -> tuple[float, float]:
    """Milliseconds a frame: drawn over the kept background, and the whole figure drawn."""
    times = playback_times(run.t[0], run.t[-1], fps=fps, duration=duration)
    frames = make_frames(run, frame_indices(run.t, times))
    scene = _Scene(frames, size=size, view=None)
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
    small = simulate(artificial_damping(class1_shell(3, 1)), (0.0, 10.0), sample_dt=0.01)
    rest = simulate(  # (what `tensegrity simulate` runs)
        artificial_damping(class1_shell(3, 1)), (0.0, 60.0), sample_dt=0.01, steady_state=True
    )
    cases = [  # name, run, suffix, frames per second, duration [s] (None: real time), size
        ("(3,1) shell, 10 s at 30 fps, MP4", small, ".mp4", 30.0, 10.0, SIZE),
        ("(3,1) shell, 10 s at 30 fps, WebM", small, ".webm", 30.0, 10.0, SIZE),
        ("(3,1) shell, 3 s at 30 fps (GIF: 33.3), GIF", small, ".gif", 30.0, 3.0, SIZE),
        (
            f"`tensegrity simulate`'s GIF: the (3,1) run until it rests ({rest.t[-1]:.2f} s) "
            f"at {VIDEO_FPS:g} fps, {VIDEO_SIZE[0]}x{VIDEO_SIZE[1]}",
            rest,
            ".gif",
            VIDEO_FPS,
            None,
            VIDEO_SIZE,
        ),
    ]
    if not quick:
        big = simulate(artificial_damping(class1_shell(30, 30)), (0.0, 0.2), sample_dt=0.01)
        cases.append(("(30,30) shell, 2 s at 30 fps, MP4", big, ".mp4", 30.0, 2.0, SIZE))
    print("| what | frames | animate | file | ms a frame: blitted | whole figure | ratio |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name, run, suffix, fps, duration, size in cases:
            path = Path(folder) / f"motion{suffix}"
            fps = frame_rate(path, fps)
            start = time.perf_counter()
            animate(run, path, fps=fps, duration=duration, size=size, progress=False)
            seconds = time.perf_counter() - start
            blitted, whole = _per_frame(run, fps, duration, size)
            n_frames = playback_times(run.t[0], run.t[-1], fps=fps, duration=duration).size
            print(
                f"| {name} | {n_frames} | {seconds:.2f} s | {path.stat().st_size / 1e6:.2f} MB "
                f"| {blitted:.1f} | {whole:.1f} | {blitted / whole:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
