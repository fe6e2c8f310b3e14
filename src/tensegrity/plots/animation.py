"""Animations of a run: MP4, WebM or GIF video of its frames (:mod:`.motion`), drawn with
matplotlib (Agg, no ``pyplot``) and encoded: MP4 (H.264) and WebM (VP8) by the ffmpeg binary of
``imageio-ffmpeg``, GIF by Pillow (one palette for all frames).

Each frame shows the structure as :mod:`tensegrity.plots.figures` draws it: rods thick and dark,
taut tendons coloured by tension on a colour bar whose range is fixed over the whole run, slack
tendons thin, dashed and red, fixed nodes as brown triangles, ball joints as open circles, point
masses as dots; the simulation time and energies in the corner.  A run with planes (the ground,
an incline, a wall) shows each as a semi-transparent patch with a grid fixed in space
(:func:`~.motion.plane_patches`), and the rod ends in contact at each frame as dots, sticking
(:data:`~.figures.STICK_COLOR`) or slipping (:data:`~.figures.SLIP_COLOR`; free ends unmarked),
with a key.  The camera and the axis limits are fixed over the run (the box of every node in
every frame, and of the patches).  A planar structure is seen from above (its plane ``z = 0``).

:func:`animate` writes the file atomically (:func:`tensegrity.io.files.atomic_path`): an
interrupted or failed animation leaves no file behind (and an older file intact).

SI units: m, s, N, J.
"""

from __future__ import annotations

import functools
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib import rc_context, rcParams
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize, to_rgb
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties, findfont
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from PIL import Image, ImageDraw, ImageFont

from tensegrity.io.files import PathLike, atomic_path
from tensegrity.plots.figures import (
    FAILURE_COLOR,
    FIXED_COLOR,
    PLANE_ALPHA,
    PLANE_COLOR,
    PLANE_GRID_COLOR,
    ROD_COLOR,
    ROD_WIDTH,
    SLACK_COLOR,
    SLIP_COLOR,
    STICK_COLOR,
    TENDON_WIDTH,
    fit_axes,
    tension_colormap,
)
from tensegrity.plots.motion import (
    Frames,
    frame_indices,
    frame_rate,
    gif_delay,
    make_frames,
    playback_times,
    tension_colors,
)

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult

__all__ = ["VIDEO_FORMATS", "animate", "render_frames"]

#: File suffixes :func:`animate` writes, and the encoder of each.
VIDEO_FORMATS = {".mp4": "libx264", ".webm": "libvpx", ".gif": "pillow"}
#: Default view of a 3-D structure: elevation and azimuth [degrees], as the still figures.
VIEW_3D = (22.0, -58.0)
#: View of a planar structure: from above its plane.
VIEW_PLANAR = (90.0, -90.0)
#: Size of a frame's text [points] (matplotlib's "small"), and the grey of its counts.
TEXT_POINTS = 10 / 1.2
TEXT_GREY = 77
#: The narrowest frame [pixels] whose text is drawn at full size; a narrower one's is scaled
#: down with its width.
LAYOUT_WIDTH = 640
#: The colour bar's axes in a video frame: left, bottom, width, height (fractions of the frame).
COLOUR_BAR = (0.86, 0.2, 0.025, 0.6)


def _video_format(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in VIDEO_FORMATS:
        raise ValueError(
            f"{path}: unknown video format {path.suffix!r}, expected one of "
            f"{', '.join(VIDEO_FORMATS)}"
        )
    return suffix


class _Scene:
    """The figure of a run: what stays the same over the run (axes, colour bar, title) drawn
    once and kept as pixels; :meth:`show` puts them back and draws a frame's rods, tendons,
    nodes and text over them (blitting: 12 times faster than drawing the whole figure for each
    frame, ``benchmarks/bench_animation.py``)."""

    def __init__(
        self, frames: Frames, *, size: tuple[int, int], view: tuple[float, float] | None
    ) -> None:
        self.frames = frames
        width = size[0]
        dpi = 100
        # a small frame's text as a LAYOUT_WIDTH frame's, scaled down (at full size the labels,
        # the colour bar and the counts ran into each other below about 480 pixels)
        scale = min(1.0, width / LAYOUT_WIDTH)
        with rc_context({"font.size": rcParams["font.size"] * scale}):
            self._draw_background(frames, size, view, dpi, scale)

    def _draw_background(
        self,
        frames: Frames,
        size: tuple[int, int],
        view: tuple[float, float] | None,
        dpi: float,
        scale: float,
    ) -> None:
        """:meth:`__init__`'s figure, its text ``scale`` times matplotlib's size."""
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

        structure = frames.structure
        width, height = size
        self.figure = figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi)
        FigureCanvasAgg(figure)
        figure.set_facecolor("white")
        # (computed_zorder off: the moving artists are drawn in their own order, over the rest)
        ax: Any = figure.add_axes((0.0, 0.05, 0.84, 0.87), projection="3d", computed_zorder=False)
        self.ax = ax
        if view is None:
            view = VIEW_3D if structure.dim == 3 else VIEW_PLANAR
        ax.view_init(elev=view[0], azim=view[1])
        fit_axes(ax, frames.scene_bounds)
        if structure.dim == 2:  # seen from above: no z axis to read
            ax.set_zticks([])
            ax.set_zlabel("")
        self.planes: list[Any] = []  # (the patches and their grid: in the background)
        if frames.contacts is not None:
            self.planes = [
                Poly3DCollection(
                    frames.contacts.patch, facecolors=PLANE_COLOR, alpha=PLANE_ALPHA, linewidths=0
                ),
                Line3DCollection(frames.contacts.grid(), colors=PLANE_GRID_COLOR, linewidths=0.5),
            ]
            for collection in self.planes:
                ax.add_collection3d(collection, autolim=False)
        empty = np.zeros((0, 2, 3))
        tendon_width = _thinned(TENDON_WIDTH, structure.n_tendons, 40)
        self.tendons = Line3DCollection(empty, linewidths=tendon_width)
        self.slack = Line3DCollection(
            empty,
            colors=SLACK_COLOR,
            linewidths=0.6 * tendon_width,
            linestyles=(0, (4, 2.5)),
        )
        self.rods = Line3DCollection(
            empty,
            colors=ROD_COLOR,
            linewidths=_thinned(ROD_WIDTH, structure.n_rods, 12),
            capstyle="round",
        )
        for collection in (self.tendons, self.slack, self.rods):
            ax.add_collection3d(collection, autolim=False)
        self.markers: list[tuple[Any, np.ndarray]] = []
        styles: tuple[tuple[np.ndarray, dict[str, Any]], ...] = (
            (frames.point_mass_nodes, dict(marker="o", ms=7, color=ROD_COLOR)),
            (frames.joint_nodes, dict(marker="o", ms=7, mfc="white", mec=ROD_COLOR, mew=1.5)),
            (frames.fixed_nodes, dict(marker="^", ms=9, color=FIXED_COLOR)),
        )
        for nodes, style in styles:
            if nodes.size:
                (line,) = ax.plot([], [], [], ls="", **style)
                self.markers.append((line, nodes))
        self.contacts: list[Any] = []  # (the sticking and the slipping ends' dots)
        if frames.contacts is not None:
            keys: list[Any] = [Patch(facecolor=PLANE_COLOR, alpha=PLANE_ALPHA, label="plane")]
            for color, name in ((STICK_COLOR, "end sticking"), (SLIP_COLOR, "end slipping")):
                style = dict(marker="o", ms=7, color=color, mec=ROD_COLOR, mew=0.8, ls="")
                self.contacts.append(ax.plot([], [], [], **style)[0])
                keys.append(Line2D([], [], label=name, **style))
            figure.legend(handles=keys, loc="lower left", fontsize="small", frameon=False)
        colour_axes = figure.add_axes(COLOUR_BAR)
        # its top left [pixels], which the frame's text keeps clear of
        self.colour_at = (
            round(COLOUR_BAR[0] * width),
            round((1.0 - sum(COLOUR_BAR[1::2])) * height),
        )
        mappable = ScalarMappable(Normalize(*frames.tension_range), tension_colormap())
        figure.colorbar(mappable, cax=colour_axes, label="tendon tension [N]")
        # the frame's text is drawn with Pillow: matplotlib's text took 9 ms of a frame's 16
        self.fonts = {
            family: _font(family, pixels=round(TEXT_POINTS * scale * dpi / 72))
            for family in ("monospace", "sans-serif")
        }
        self.text_at = (round(0.02 * width), round(0.03 * height))  # (top left)
        self.count_at = (round(0.98 * width), round(0.07 * height))  # (top right)
        figure.text(
            0.98, 0.97, frames.title[:60], va="top", ha="right", fontsize="small", color="0.3"
        )
        # drawn over the background each frame, in this order (rods over tendons)
        self.moving: tuple[Any, ...] = (
            self.tendons,
            self.slack,
            self.rods,
            *(line for line, _ in self.markers),
            *self.contacts,
        )
        for artist in self.moving:
            artist.set_animated(True)  # left out of the figure's own drawing
        canvas = figure.canvas
        canvas.draw()  # the background, and the camera's projection (ax.M) of every frame
        self.background = canvas.copy_from_bbox(figure.bbox)  # type: ignore[attr-defined]

    def show(self, k: int) -> np.ndarray:
        """Draw frame ``k``; its pixels, shape (height, width, 3), uint8."""
        frames, structure = self.frames, self.frames.structure
        slack = frames.slack[k]
        pairs = structure.tendon_nodes
        self.tendons.set_segments(frames.segments(k, pairs[~slack]))
        self.tendons.set_colors(
            tension_colors(frames.tendon_tension[k][~slack], frames.tension_range)
        )
        self.slack.set_segments(frames.segments(k, pairs[slack]))
        self.rods.set_segments(frames.segments(k, structure.rod_nodes))
        for line, nodes in self.markers:
            line.set_data_3d(*frames.node_position[k][nodes].T)
        if frames.contacts is not None:
            for line, nodes in zip(self.contacts, frames.contacts.ends(k), strict=True):
                line.set_data_3d(*frames.node_position[k][nodes].T)
        canvas: Any = self.figure.canvas
        canvas.restore_region(self.background)
        for collection in (self.tendons, self.slack, self.rods):
            collection.do_3d_projection()  # (what the axes' own drawing does first)
        for artist in self.moving:
            self.ax.draw_artist(artist)
        return self.labelled(k)

    def labelled(self, k: int) -> np.ndarray:
        """The figure's pixels as drawn now, shape (height, width, 3), uint8, with frame ``k``'s
        time, energies and counts written over them."""
        frames = self.frames
        lines = [f"t = {frames.t[k]:8.3f} s"]
        if frames.energy:
            lines += [
                f"E       = {frames.energy['total'][k]:.5g} J",
                f"E_kin   = {frames.energy['kinetic'][k]:.4g} J",
                f"E_el    = {frames.energy['elastic'][k]:.4g} J",
            ]
        n_slack = int(frames.slack[k].sum())
        count = (
            f"{frames.structure.n_rods} rods, {frames.structure.n_tendons} tendons, "
            f"{n_slack} slack" + (" (dashed)" if n_slack else "")
        )
        if frames.contacts is not None:
            stick, slip = frames.contacts.ends(k)
            count += f", {stick.size} ends sticking, {slip.size} slipping"
        canvas: Any = self.figure.canvas
        rgba = np.asarray(canvas.buffer_rgba())
        picture = np.empty((*rgba.shape[:2], 3), dtype=np.uint8)
        for channel in range(3):  # (5x faster than copying rgba[..., :3] at once: 0.4 ms)
            picture[..., channel] = rgba[..., channel]
        for mask, at, fill in self.text_layout(lines, count):
            _write(picture, mask, at, fill=fill)
        return picture

    def text_layout(
        self, lines: list[str], count: str
    ) -> list[tuple[np.ndarray, tuple[int, int], int]]:
        """Where a frame's text goes, as ``(coverage mask, top left [pixels], grey)``: the
        ``lines`` (time, energies) at the top left; the ``count`` right-aligned at the top
        right, broken after commas into lines narrow enough to stay clear of them and few enough
        to end above the colour bar, or else left-aligned under them, as wide as the colour bar
        leaves room for (a small picture)."""
        font = self.fonts["sans-serif"]
        block = _text_mask("\n".join(lines), self.fonts["monospace"])
        left, top = self.text_at
        right, count_top = self.count_at
        bar_left, bar_top = self.colour_at
        margin = left
        step = round(1.25 * font.size)
        rows = _rows(count, font, right - (left + block.shape[1]) - margin)
        beside = rows is not None and count_top + len(rows) * step <= bar_top
        if not beside:
            rows = _rows(count, font, bar_left - margin - left) or [count]
            count_top = top + block.shape[0] + margin
        placed = [(block, (left, top), 0)]
        for k, row in enumerate(rows or ()):
            mask = _text_mask(row, font)  # (the same over many frames)
            x = right - mask.shape[1] if beside else left
            placed.append((mask, (x, count_top + k * step), TEXT_GREY))
        return placed


def _rows(text: str, font: ImageFont.FreeTypeFont, width: int) -> list[str] | None:
    """``text`` broken after its commas into the fewest lines at most ``width`` pixels wide in
    ``font`` (filled greedily; each line measured with a comma after it), or None if one of its
    parts is wider."""
    lines: list[list[str]] = []
    for part in text.split(", "):
        if lines and _text_mask(", ".join([*lines[-1], part]) + ",", font).shape[1] <= width:
            lines[-1].append(part)
        elif _text_mask(part + ",", font).shape[1] <= width:
            lines.append([part])
        else:
            return None
    last = len(lines) - 1
    return [", ".join(parts) + ("," if k < last else "") for k, parts in enumerate(lines)]


@functools.lru_cache(maxsize=256)
def _text_mask(text: str, font: ImageFont.FreeTypeFont) -> np.ndarray:
    """The coverage (0-255) of ``text`` drawn by Pillow in ``font``, its box's top left at the
    origin: shape (height, width), uint8.  Cached: a frame's counts repeat over many frames
    (drawing them took 0.26 ms of a frame's 5)."""
    box = ImageDraw.Draw(Image.new("L", (1, 1))).multiline_textbbox((0, 0), text, font=font)
    mask = Image.new("L", (math.ceil(box[2]), math.ceil(box[3])))
    ImageDraw.Draw(mask).multiline_text((0, 0), text, font=font, fill=255)
    coverage = np.array(mask)
    coverage.flags.writeable = False  # (shared by the cache)
    return coverage


def _write(picture: np.ndarray, mask: np.ndarray, at: tuple[int, int], *, fill: int) -> None:
    """Write the text of ``mask`` (its coverage, 0-255: :func:`_text_mask`) into ``picture``
    (height, width, 3) in the grey ``fill`` (0-255), its top left at pixel ``at`` (what falls
    outside the picture cut off): only the text's box is blended (converting the whole frame to
    an image and back took 3 ms)."""
    height, width = mask.shape
    x, y = at
    left, top = max(0, -x), max(0, -y)  # the mask's part left or above the picture
    region = picture[y + top : y + height, x + left : x + width]
    alpha = mask[top : top + region.shape[0], left : left + region.shape[1], None]
    region[...] = np.rint(region * (1.0 - alpha / 255.0) + fill * (alpha / 255.0))


def _font(family: str, *, pixels: int) -> ImageFont.FreeTypeFont:
    """matplotlib's font of ``family`` (DejaVu, which it ships), ``pixels`` high, for Pillow."""
    return ImageFont.truetype(findfont(FontProperties(family=[family])), size=pixels)


def _thinned(width: float, count: int, up_to: int) -> float:
    """A line width [points]: ``width`` for up to ``up_to`` lines, thinner as ``1 / sqrt(count)``
    for more (a large shell would be a solid block), at least 0.25."""
    return max(0.25, width * min(1.0, (up_to / max(count, 1)) ** 0.5))


def render_frames(
    frames: Frames,
    *,
    size: tuple[int, int] = (800, 640),
    view: tuple[float, float] | None = None,
    progress: bool | None = None,
) -> Iterator[np.ndarray]:
    """The pictures of ``frames``, one by one: arrays (height, width, 3) of uint8.

    Parameters
    ----------
    frames : Frames
    size : (int, int)
        Width and height [pixels], each a multiple of 16 (what video encoders need) and >= 160.
    view : (float, float), optional
        Elevation and azimuth of the camera [degrees]; default :data:`VIEW_3D`, or
        :data:`VIEW_PLANAR` for a planar structure.
    progress : bool, optional
        Show a progress bar (tqdm) on stderr; default: when stderr is a terminal.
    """
    width, height = size
    if width % 16 or height % 16 or min(width, height) < 160:
        raise ValueError(f"size: width and height must be multiples of 16, >= 160, got {size}")
    from tqdm import tqdm

    if progress is None:
        progress = sys.stderr.isatty()
    scene = _Scene(frames, size=size, view=view)
    for k in tqdm(range(frames.n_frames), desc="animate", unit="frame", disable=not progress):
        yield scene.show(k)


def animate(
    result: SimulationResult,
    path: PathLike,
    *,
    fps: float = 30.0,
    duration: float | None = None,
    speed: float | None = None,
    size: tuple[int, int] = (800, 640),
    view: tuple[float, float] | None = None,
    progress: bool | None = None,
) -> Path:
    """Write an animation of ``result`` to ``path`` (``.mp4``, ``.webm`` or ``.gif``), atomically.

    Parameters
    ----------
    result : SimulationResult
        A run in memory or read back (:func:`tensegrity.io.trajectory.read_trajectory`).
    path : str or os.PathLike
        The video file; its suffix picks the format (:data:`VIDEO_FORMATS`).  Its folder must
        exist.
    fps : float
        Frames per second of the video; a GIF's is :func:`~.motion.frame_rate`'s (its frame
        delays are whole hundredths of a second: 33.3 for 30, 25 for 25).
    duration, speed : float, optional
        Length of the video [s], or simulated seconds per second of video (one of them; default:
        real time, at most :data:`tensegrity.plots.motion.MAX_REAL_TIME` s of video).  Each
        frame shows the last sample at or before its time (:func:`~.motion.playback_times`).
    size : (int, int)
        Width and height [pixels], multiples of 16.
    view : (float, float), optional
        Camera elevation and azimuth [degrees].
    progress : bool, optional
        Progress bar on stderr; default: when stderr is a terminal.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    suffix = _video_format(path)
    fps = frame_rate(path, fps)
    times = playback_times(result.t[0], result.t[-1], fps=fps, duration=duration, speed=speed)
    frames = make_frames(result, frame_indices(result.t, times))
    pictures = render_frames(frames, size=size, view=view, progress=progress)
    contact_colors = () if frames.contacts is None else (STICK_COLOR, SLIP_COLOR)
    with atomic_path(path) as tmp:
        _encode(tmp, suffix, pictures, fps, contact_colors)
    return path


def _gif_palette(first: np.ndarray, extra_colors: tuple[str, ...] = ()) -> Image.Image:
    """The 256 colours of every frame of a GIF: those of the first frame (background, axes,
    the whole colour bar, text, rods), with the slack tendons', supports' and failing members'
    colours and ``extra_colors`` (the contacts' of a run with planes), which it may not show,
    added (Pillow's maximum-coverage quantiser: it keeps the
    white background white).  One palette for all frames: quantising each frame on its own took
    35 ms of a frame's 42 (mapping onto a given palette takes 1 ms), and the frames' shared
    colours keep the file small."""
    colors = (SLACK_COLOR, FIXED_COLOR, FAILURE_COLOR, *extra_colors)
    extra = np.array([to_rgb(c) for c in colors]) * 255
    swatch = np.repeat(np.rint(extra).astype(np.uint8), first.shape[1], axis=0)
    sample = np.concatenate([first.reshape(-1, 3), swatch])[None]
    return Image.fromarray(sample).quantize(colors=256, method=Image.Quantize.MAXCOVERAGE)


def _encode(
    tmp: Path,
    suffix: str,
    pictures: Iterator[np.ndarray],
    fps: float,
    extra_colors: tuple[str, ...] = (),
) -> None:
    """Encode ``pictures`` into ``tmp`` as the video format of ``suffix`` (a GIF's palette with
    ``extra_colors`` too: :func:`_gif_palette`)."""
    first = next(pictures, None)
    if first is None:
        raise ValueError("no frames to encode")
    if suffix == ".gif":
        palette = _gif_palette(first, extra_colors)
        indexed = (
            Image.fromarray(picture).quantize(palette=palette, dither=Image.Dither.NONE)
            for picture in pictures
        )
        Image.fromarray(first).quantize(palette=palette, dither=Image.Dither.NONE).save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=indexed,
            duration=10 * gif_delay(fps),  # [ms], whole hundredths of a second
            loop=0,
        )
        return
    import imageio_ffmpeg

    height, width = first.shape[:2]
    extra = (
        ["-b:v", "2M", "-deadline", "realtime", "-cpu-used", "8"]
        if suffix == ".webm"
        else ["-preset", "veryfast"]
    )
    writer = imageio_ffmpeg.write_frames(
        str(tmp),
        (width, height),
        fps=fps,
        codec=VIDEO_FORMATS[suffix],
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        macro_block_size=16,
        output_params=["-f", suffix[1:], *extra],
        ffmpeg_log_level="error",
    )
    writer.send(None)  # start ffmpeg
    try:
        writer.send(first)
        for picture in pictures:
            writer.send(picture)
    finally:
        writer.close()
