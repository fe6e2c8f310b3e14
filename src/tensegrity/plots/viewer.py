"""The interactive viewer: one self-contained HTML page of a run (or of a structure) that works
offline, in any browser with WebGL.

The page inlines three.js (the build in ``vendor/three-viewer.min.js``: three.js and its
OrbitControls from the npm package ``three``, MIT licence in ``vendor/three-LICENSE``; see
``vendor/README.md``), the viewer's own script (``viewer.js``) and the run's frames
(:mod:`.motion`) as JSON: node positions and tendon tensions as base64 little-endian Float32,
frame after frame.  Nothing is fetched when the page is viewed.

The page shows rods as dark cylinders, taut tendons coloured by tension (a legend with the range,
fixed over the whole run), slack tendons dashed red, fixed nodes as brown cones, ball joints as
light spheres and point masses as dark spheres.  Drag to orbit, scroll to zoom, right-drag to
pan; play, pause, speed and a time slider; hover a member to read its name, length [m] and
tension [N], click it to keep that in the corner.

A run whose members have a design (materials and sections: :class:`~.motion.MemberCheck`)
also carries each member's utilisation at each frame (base64 Float32, rods and tendons,
:mod:`tensegrity.design.utilisation`), and the page offers a colour mode: "tension" (the
above) or "utilisation": rods and taut tendons on the tension colour map over the fixed scale
``0 .. max(1, largest utilisation of the run)``, members above 1 in the failure colour
(:data:`~.figures.FAILURE_COLOR`); hovering a member shows its utilisation too.  Without a
design the page has neither the data nor the switch.

A run with planes (the ground, an incline, a wall) shows each plane as a semi-transparent patch
with a grid fixed in space (:func:`~.motion.plane_patches`: the footprint of the run's nodes on
it, with a margin), and the rod ends in contact at each frame as spheres coloured by their mode,
sticking (:data:`~.figures.STICK_COLOR`) or slipping (:data:`~.figures.SLIP_COLOR`; free ends
unmarked), with a key in the legend.  Its data add ``"contacts"`` (:func:`viewer_data`); a run
without planes has neither.

A long or large run is decimated to at most ``max_frames`` frames and ``max_bytes`` of positions
and tensions (:func:`frame_budget`), the frames spread evenly over the run.
"""

from __future__ import annotations

import base64
import html as html_text
import json
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.io.files import PathLike, atomic_path
from tensegrity.model.structure import Structure
from tensegrity.plots.figures import (
    FAILURE_COLOR,
    FIXED_COLOR,
    PLANE_ALPHA,
    PLANE_COLOR,
    PLANE_GRID_COLOR,
    ROD_COLOR,
    SLACK_COLOR,
    SLIP_COLOR,
    STICK_COLOR,
    tension_colormap,
)
from tensegrity.plots.motion import (
    MAX_BYTES,
    MAX_FRAMES,
    MAX_REAL_TIME,
    Frames,
    MemberCheck,
    decimated_indices,
    frame_budget,
    make_frames,
    structure_frames,
)

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult

__all__ = [
    "MAX_BYTES",
    "MAX_FRAMES",
    "HtmlText",
    "frame_budget",
    "html",
    "notebook_html",
    "read_viewer_data",
    "view",
    "viewer_data",
]

JOINT_COLOR = "#d9d9d9"


def _base64(array: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def viewer_data(frames: Frames) -> dict[str, Any]:
    """The JSON the page reads, under the names of :class:`~.motion.Frames` and
    :class:`SimulationResult`: ``t`` (F,) [s], ``node_position`` ``(F, N, 3)`` [m] and
    ``tendon_tension`` ``(F, S)`` [N] as base64 little-endian Float32, ``rod_nodes`` and
    ``tendon_nodes`` as base64 Int32, ``tendon_name``,
    and the names, markers, colours and ranges the page draws with; with the members'
    utilisation (``frames.utilisation``), ``"utilisation"``: ``"rods"`` ``(F, R)`` and
    ``"tendons"`` ``(F, S)`` as base64 Float32 and ``"high"``, the top of its scale; with
    planes (``frames.contacts``), ``"contacts"``: ``"patch"`` ``(P, 4, 3)`` [m] and ``"normal"``
    ``(P, 3)`` of each plane, ``"cell"`` [m] of their grid, ``"n_pairs"`` (CP), ``"node"``
    ``(CP,)`` as base64 Int32 and ``"mode"`` ``(F, CP)`` as base64 Int8 (0 free, 1 slip,
    2 stick) (and ``"bounds"`` takes in the patches)."""
    structure = frames.structure
    span = float(np.max(frames.bounds[1] - frames.bounds[0])) or 1.0
    rod_length = float(np.median(structure.rod_length)) if structure.n_rods else span
    data = {
        "format": "tensegrity-viewer",
        "version": 2,
        "title": frames.title,
        "dim": structure.dim,
        "n_frames": frames.n_frames,
        "n_nodes": structure.n_nodes,
        "n_rods": structure.n_rods,
        "n_tendons": structure.n_tendons,
        "t": frames.t.tolist(),
        "sample_index": frames.index.tolist(),
        "energy": {name: values.tolist() for name, values in frames.energy.items()},
        "node_position": _base64(frames.node_position, "<f4"),
        "tendon_tension": _base64(frames.tendon_tension, "<f4"),
        "rod_nodes": _base64(structure.rod_nodes, "<i4"),
        "tendon_nodes": _base64(structure.tendon_nodes, "<i4"),
        "tendon_name": list(structure.tendon_name),
        "fixed": frames.fixed_nodes.tolist(),
        "joints": frames.joint_nodes.tolist(),
        "point_masses": frames.point_mass_nodes.tolist(),
        "tension_range": list(frames.tension_range),
        "bounds": frames.scene_bounds.tolist(),
        "rod_radius": 0.012 * min(rod_length, span),
        "colormap": np.round(tension_colormap()(np.linspace(0, 1, 256))[:, :3], 5).tolist(),
        "colors": {
            "rod": ROD_COLOR,
            "slack": SLACK_COLOR,
            "fixed": FIXED_COLOR,
            "joint": JOINT_COLOR,
        },
        "max_real_time": MAX_REAL_TIME,
    }
    if frames.utilisation is not None:
        data["utilisation"] = {
            "rods": _base64(frames.utilisation.rod, "<f4"),
            "tendons": _base64(frames.utilisation.tendon, "<f4"),
            "high": frames.utilisation.high,
        }
        data["colors"]["failure"] = FAILURE_COLOR
    if frames.contacts is not None:
        contacts = frames.contacts
        data["contacts"] = {
            "patch": contacts.patch.tolist(),
            "normal": contacts.normal.tolist(),
            "cell": contacts.cell,
            "n_pairs": int(contacts.node.size),
            "node": _base64(contacts.node, "<i4"),
            "mode": _base64(contacts.mode, "i1"),
        }
        data["colors"] |= {
            "plane": PLANE_COLOR,
            "plane_grid": PLANE_GRID_COLOR,
            "plane_alpha": PLANE_ALPHA,
            "stick": STICK_COLOR,
            "slip": SLIP_COLOR,
        }
    return data


def _frames(
    what: SimulationResult | Structure | Frames,
    *,
    max_frames: int,
    max_bytes: int,
    check: MemberCheck | None,
) -> Frames:
    if check is not None and isinstance(what, Structure | Frames):
        raise ValueError("check: the design of a run's members, for a run only")
    if isinstance(what, Frames):
        return what
    if isinstance(what, Structure):
        return structure_frames(what)
    budget = frame_budget(
        what.structure,
        max_frames=max_frames,
        max_bytes=max_bytes,
        utilisation=check is not None,
        planes=len(what.planes),
    )
    return make_frames(what, decimated_indices(what.t.size, budget), check=check)


def _asset(name: str) -> str:
    return resources.files("tensegrity.plots").joinpath(name).read_text(encoding="utf-8")


def _script(text: str) -> str:
    """A script to inline in ``<script>``: refused if ``</script`` or ``<!--`` in it would end or
    change that element (the assets have neither; JSON is escaped by :func:`_json`)."""
    lowered = text.lower()
    if "</script" in lowered or "<!--" in lowered:
        raise RuntimeError("an inlined script holds '</script' or '<!--'")
    return text


def _json(data: dict[str, Any]) -> str:
    """``data`` as JSON safe inside ``<script>``: every ``<`` written ``\\u003c``."""
    return json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")


def html(
    what: SimulationResult | Structure | Frames,
    *,
    max_frames: int = MAX_FRAMES,
    max_bytes: int = MAX_BYTES,
    title: str | None = None,
    check: MemberCheck | None = None,
) -> str:
    """The viewer page of a run, a structure (at rest) or frames, as one HTML text.

    Parameters
    ----------
    what : SimulationResult, Structure or Frames
        A run (decimated to :func:`frame_budget` frames, spread evenly, first and last kept),
        a structure (one frame; tensions from its tendons' stretch) or frames made with
        :mod:`tensegrity.plots.motion`.
    max_frames : int
        Most frames in the page.
    max_bytes : int
        Most bytes of Float32 positions and tensions (and utilisations) in the page (before
        base64).
    title : str, optional
        The page's title; default: the counts of the structure.
    check : MemberCheck, optional
        For a run whose members have a design: the page colours them by utilisation too
        (frames made with :func:`~.motion.make_frames`'s ``check`` carry it already).

    Returns
    -------
    str
        A complete HTML document, self-contained (no network needed to view it).
    """
    frames = _frames(what, max_frames=max_frames, max_bytes=max_bytes, check=check)
    structure = frames.structure
    if title is None:
        title = (
            f"tensegrity: {structure.n_nodes} nodes, {structure.n_rods} rods, "
            f"{structure.n_tendons} tendons"
        )
    return _PAGE.format(
        title=html_text.escape(title),
        subtitle=html_text.escape(frames.title),
        data=_json(viewer_data(frames)),
        three=_script(_asset("vendor/three-viewer.min.js")),
        viewer=_script(_asset("viewer.js")),
    )


def view(
    result: SimulationResult | Structure | Frames,
    path: PathLike,
    *,
    max_frames: int = MAX_FRAMES,
    max_bytes: int = MAX_BYTES,
    title: str | None = None,
    check: MemberCheck | None = None,
) -> Path:
    """Write the viewer page of ``result`` (see :func:`html`) to ``path``, atomically; the
    folder must exist.  Returns ``path``."""
    text = html(result, max_frames=max_frames, max_bytes=max_bytes, title=title, check=check)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path


class HtmlText(str):
    """Text of HTML that a notebook (Jupyter, VS Code, marimo) or a sphinx-gallery page shows
    rendered when it is a cell's value (``_repr_html_``); otherwise a plain ``str``."""

    def _repr_html_(self) -> str:
        return str(self)


def notebook_html(
    what: SimulationResult | Structure | Frames,
    *,
    max_frames: int = 100,
    max_bytes: int = 8_000_000,
    height: int = 520,
    check: MemberCheck | None = None,
) -> HtmlText:
    """The viewer inside an ``<iframe srcdoc>``, for Jupyter (:func:`tensegrity.plots.show_inline`):
    the page of :func:`html` (``check``: a run's members by utilisation too), with smaller default
    limits, ``height`` pixels high.  As a cell's value it shows as the viewer in any front end
    that renders ``_repr_html_`` (:class:`HtmlText`)."""
    page = html(what, max_frames=max_frames, max_bytes=max_bytes, check=check)
    return HtmlText(
        f'<iframe srcdoc="{html_text.escape(page, quote=True)}" '
        f'style="width:100%;height:{int(height)}px;border:1px solid #ddd" '
        'sandbox="allow-scripts"></iframe>'
    )


def read_viewer_data(text: str) -> dict[str, Any]:
    """The data of a viewer page (:func:`html`), its arrays decoded: ``node_position`` (F, N, 3)
    and ``tendon_tension`` (F, S) as float32, ``rod_nodes`` (R, 2) and ``tendon_nodes`` (S, 2)
    as int32,
    (a run whose members have a design) ``utilisation["rods"]`` (F, R) and
    ``utilisation["tendons"]`` (F, S) as float32, and (a run with planes) ``contacts["node"]``
    (CP,) as int32 and ``contacts["mode"]`` (F, CP) as int8."""
    start = text.index(_DATA_OPEN) + len(_DATA_OPEN)
    data = json.loads(text[start : text.index("</script>", start)])
    F, N, R, S = data["n_frames"], data["n_nodes"], data["n_rods"], data["n_tendons"]
    decoded = [
        (data, "node_position", "<f4", (F, N, 3)),
        (data, "tendon_tension", "<f4", (F, S)),
        (data, "rod_nodes", "<i4", (R, 2)),
        (data, "tendon_nodes", "<i4", (S, 2)),
    ]
    if "utilisation" in data:
        u = data["utilisation"]
        decoded += [(u, "rods", "<f4", (F, R)), (u, "tendons", "<f4", (F, S))]
    if "contacts" in data:
        c, CP = data["contacts"], data["contacts"]["n_pairs"]
        decoded += [(c, "node", "<i4", (CP,)), (c, "mode", "i1", (F, CP))]
    for where, key, dtype, shape in decoded:
        where[key] = np.frombuffer(base64.b64decode(where[key]), dtype=dtype).reshape(shape)
    return data


_DATA_OPEN = '<script type="application/json" id="tensegrity-data">'

_PAGE = (
    """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
html, body {{ margin: 0; height: 100%; font: 13px system-ui, sans-serif; color: #222; }}
#view {{ position: absolute; inset: 0 0 52px 0; background: #fff; }}
#bar {{ position: absolute; left: 0; right: 0; bottom: 0; height: 52px; display: flex;
  gap: 10px; align-items: center; padding: 0 12px; border-top: 1px solid #ddd;
  background: #fafafa; }}
#time {{ flex: 1; }}
#clock {{ font-family: monospace; white-space: pre; min-width: 24em; }}
#head {{ position: absolute; left: 12px; top: 8px; pointer-events: none; }}
#head b {{ font-size: 14px; }}
#legend {{ position: absolute; right: 12px; top: 12px; background: rgba(255,255,255,.85);
  padding: 6px 8px; border: 1px solid #ddd; }}
#legend canvas {{ vertical-align: top; border: 1px solid #aaa; }}
#info {{ position: absolute; right: 12px; bottom: 64px; white-space: pre; font-family: monospace;
  background: rgba(255,255,255,.85); }}
#tip {{ position: fixed; display: none; white-space: pre; font-family: monospace;
  background: #fffbe6; border: 1px solid #caa; padding: 3px 6px; pointer-events: none; }}
.key {{ display: inline-block; width: 22px; height: 0; margin-right: 6px; vertical-align: middle; }}
</style></head>
<body>
<div id="view"></div>
<div id="head"><b>{title}</b><br><span>{subtitle}</span><br><span id="counts"></span></div>
<div id="legend">tendon tension<br>
<canvas id="colorbar" width="16" height="140"></canvas>
<span style="display:inline-block;height:140px;position:relative;width:70px">
<span id="t-high" style="position:absolute;top:0"></span>
<span id="t-low" style="position:absolute;bottom:0"></span></span><br>
<span class="key" style="border-top:2px dashed #d62728"></span>slack tendon<br>
<span class="key" style="border-top:5px solid #26282b"></span>rod<br>
<span style="color:#8c564b">&#9650;</span> fixed node &nbsp;
<span style="color:#999">&#9679;</span> joint</div>
<div id="info"></div><div id="tip"></div>
<div id="bar"><button id="play">play</button>
<label>speed <select id="speed"><option value="0.25">&times;0.25</option>
<option value="0.5">&times;0.5</option><option value="1" selected>&times;1</option>
<option value="2">&times;2</option><option value="4">&times;4</option></select></label>
<span id="rate" style="color:#777"></span>
<input id="time" type="range" min="0" max="0" value="0" step="1">
<span id="clock"></span></div>
"""
    + _DATA_OPEN
    + """{data}</script>
<script>{three}</script>
<script>{viewer}</script>
</body></html>
"""
)
