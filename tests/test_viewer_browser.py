"""The viewer page (plots.viewer) in a real browser: headless Chromium (Debian's ``chromium``;
``.ci/run`` installs it) driven by Playwright, with every network request refused.  The page
must draw the structure without a console error, move in time (two screenshots differ; the
slider moves the time), hold the run's node positions to float32 precision and colour each
tendon by its tension (issue 15); a run whose members have a design switches to colouring every
member by its utilisation, failing ones in the failure colour (issue 18).  Skipped only if
Chromium or Playwright is missing."""

from __future__ import annotations

import io
import shutil

import numpy as np
import pytest
from matplotlib.colors import to_rgb

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.model.planar import planar_two_rod
from tensegrity.model.shell import class2_shell
from tensegrity.plots.figures import ROD_COLOR, tension_colormap, utilisation_colors
from tensegrity.plots.viewer import notebook_html, read_viewer_data, view
from test_kernel_system import point_mass_between_anchors
from test_utilisation_colours import designed_prism

sync_api = pytest.importorskip("playwright.sync_api")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
if CHROMIUM is None:
    pytest.skip("no chromium on this machine (.ci/run installs it)", allow_module_level=True)

Image = pytest.importorskip("PIL.Image")


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as playwright:
        # WebGL without a GPU: SwiftShader, Chromium's software renderer
        chromium = playwright.chromium.launch(
            executable_path=CHROMIUM,
            args=["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
        )
        yield chromium
        chromium.close()


class Page:
    """A viewer page open in the browser, its console errors and refused requests recorded."""

    def __init__(self, browser, path, *, viewer=True):
        self.errors: list[str] = []
        self.requests: list[str] = []
        self.page = browser.new_page(viewport={"width": 900, "height": 640})
        self.page.on(
            "console", lambda m: m.type == "error" and self.errors.append(m.text)
        )  # fmt: skip
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.route("**/*", self._route)
        self.page.goto(path.as_uri())
        if viewer:  # else a page that holds the viewer in a frame
            self.page.wait_for_function("window.tensegrityViewer && tensegrityViewer.ready")

    def _route(self, route):
        url = route.request.url
        if url.startswith("file:"):
            route.continue_()
        else:  # no network: anything else is refused, and recorded
            self.requests.append(url)
            route.abort()

    def call(self, script):
        return self.page.evaluate(script)

    def picture(self):
        """The 3-D view (without the page's text and controls) as RGB, (H, W, 3)."""
        box = self.page.locator("#view canvas").bounding_box()
        png = self.page.screenshot(clip=box)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)

    def check_clean(self):
        assert self.errors == [], self.errors
        assert self.requests == [], self.requests


def drawn(picture):
    """Pixels that are not the white background."""
    return picture.min(axis=-1) < 235


@pytest.fixture(scope="module")
def shell31():
    return simulate(artificial_damping(class1_shell(3, 1)), (0.0, 2.0), sample_dt=0.01)


@pytest.fixture(scope="module")
def page31(browser, shell31, tmp_path_factory):
    path = view(shell31, tmp_path_factory.mktemp("page") / "view.html", max_frames=50)
    page = Page(browser, path)
    yield page, read_viewer_data(path.read_text())
    page.page.close()


def _member_under_pointer(page, xs, ys):
    """``(px, py, info)``: the first point of the grid ``xs`` x ``ys`` (fractions of the view,
    row by row) with a member under it, and what the viewer says of that member."""
    canvas = page.page.locator("#view canvas").bounding_box()
    for y in ys:
        for x in xs:
            px = round(canvas["x"] + x * canvas["width"])
            py = round(canvas["y"] + y * canvas["height"])
            info = page.call(f"tensegrityViewer.pickAt({px}, {py})")
            if info:
                return px, py, info
    raise AssertionError("no member under the pointer in the middle of the view")


def test_the_structure_is_drawn_and_moves(page31, tmp_path):
    page, _ = page31
    page.call("tensegrityViewer.setFrame(0)")
    first = page.picture()
    page.call("tensegrityViewer.setFrame(5)")  # 0.2 s: the shell is contracting fast
    later = page.picture()
    Image.fromarray(first.astype(np.uint8)).save(tmp_path / "first.png")
    assert drawn(first).sum() > 3000, "too few pixels drawn: is the structure there?"
    assert drawn(later).sum() > 3000
    differ = np.abs(first - later).max(axis=-1) > 60
    assert differ.sum() > 1000, "the two times look the same"
    page.check_clean()


def test_the_slider_moves_the_time(page31):
    page, data = page31
    page.call("tensegrityViewer.setFrame(0)")
    assert page.call("tensegrityViewer.time()") == 0.0
    assert "t = 0.000 s" in page.page.inner_text("#clock")
    box = page.page.locator("#time").bounding_box()
    page.page.mouse.click(box["x"] + 0.75 * box["width"], box["y"] + box["height"] / 2)
    frame = page.call("tensegrityViewer.frame()")
    assert 30 <= frame <= 45
    t = data["t"][frame]
    assert page.call("tensegrityViewer.time()") == t > 1.0
    assert f"t = {t:.3f} s" in page.page.inner_text("#clock")
    page.check_clean()


def test_play_advances_the_frames(page31):
    page, _ = page31
    page.call("tensegrityViewer.setFrame(0)")
    page.call("tensegrityViewer.play()")
    page.page.wait_for_function("tensegrityViewer.frame() > 3", timeout=10_000)
    page.call("tensegrityViewer.pause()")
    page.check_clean()


def test_node_positions_in_the_page_are_the_run_s_to_float32(page31, shell31):
    page, data = page31
    for frame in (0, 17, data["n_frames"] - 1):
        sample = data["sample_index"][frame]
        shown = np.array(page.call(f"tensegrityViewer.nodePositions({frame})"), dtype=np.float32)
        expected = shell31.node_position[sample].astype(np.float32).ravel()
        np.testing.assert_array_equal(shown, expected)


def test_tendon_colour_follows_its_tension(page31, shell31):
    page, data = page31
    frame = 0  # all taut, tensions from 4.5 to 99 N
    page.call(f"tensegrityViewer.setFrame({frame})")
    tension = data["tendon_tension"][frame].astype(float)
    low, high = data["tension_range"]
    colours = np.array([page.call(f"tensegrityViewer.tendonColor({j})") for j in range(24)])
    expected = tension_colormap()((tension - low) / (high - low))[:, :3]
    np.testing.assert_allclose(colours, expected, atol=0.02)  # a 256-colour table
    # the most and least tense tendons are far apart on the map
    assert np.abs(colours[tension.argmax()] - colours[tension.argmin()]).sum() > 0.5


def _distances(points, a, b):
    """Distances (P, M) from the points (P, 2) to the segments from ``a`` (M, 2) to ``b``."""
    ab = b - a
    along = ((points[:, None] - a) * ab).sum(-1) / np.maximum((ab**2).sum(-1), 1e-12)
    nearest = a + np.clip(along, 0.0, 1.0)[..., None] * ab
    return np.linalg.norm(points[:, None] - nearest, axis=-1)


def tendon_pixels(page, data, frame):
    """``{j: pixels (n, 3)}``: for each taut tendon ``j`` of ``frame`` as drawn now, the colour
    (0..255) of its most covered pixel at points every 2 px along the middle of its drawn
    segment (40 %), at the points 4 px or more clear of every other tendon and 8 px or more of
    every rod; a tendon without such a point is left out.

    Tendons are unlit 1 px lines (``LineBasicMaterial``): a pixel the line covers has its colour
    exactly (to 8-bit rounding); antialiasing blends a partly covered pixel with the white
    background, ``alpha * colour + (1 - alpha) * white``, lighter in every channel, so the
    darkest pixel of the 3 x 3 around a point is the one the line covers most."""
    box = page.page.locator("#view canvas").bounding_box()
    picture = page.picture()
    screen = np.array(
        page.page.evaluate(
            "ps => ps.map(p => tensegrityViewer.toScreen(...p))",
            data["node_position"][frame].tolist(),
        )
    ) - [box["x"], box["y"]]
    rods, tendons = screen[data["rod_nodes"]], screen[data["tendon_nodes"]]  # (M, 2 ends, 2)
    taut = np.flatnonzero(data["tendon_tension"][frame] > 0)
    pixels = {}
    for j in taut:
        a, b = tendons[j]
        n = max(int(0.2 * np.linalg.norm(b - a)), 1)
        points = a + np.linspace(0.3, 0.7, n)[:, None] * (b - a)
        others = np.delete(tendons, j, axis=0)
        clear = (
            _distances(points, others[:, 0], others[:, 1]).min(axis=1, initial=np.inf) >= 4
        ) & (_distances(points, rods[:, 0], rods[:, 1]).min(axis=1, initial=np.inf) >= 8)
        found = []
        for x, y in np.floor(points[clear]).astype(int):
            around = picture[y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 3)
            found.append(around[around.sum(axis=1).argmin()])
        if found:
            pixels[int(j)] = np.array(found)
    return pixels


def legend_colours(page):
    """The legend's colour bar as drawn, row by row: (rows, 3), 0..255."""
    rgba = page.call(
        "(() => { const c = document.getElementById('colorbar');"
        " return Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height).data); })()"
    )
    width = page.call("document.getElementById('colorbar').width")
    return np.array(rgba).reshape(-1, width, 4)[:, width // 2, :3]


def check_tendon_pixels(page, data, frame, expected):
    """The drawn tendons of ``frame`` (:func:`tendon_pixels`, two thirds of the taut ones seen)
    in ``expected`` (S, 3) (0..255), the colours the legend gives them.  Every pixel read is a
    blend of its tendon's colour with white (antialiasing), at least half covered; three
    quarters of the tendons seen cover a pixel fully somewhere (the others, at some slopes,
    cover 3 of its 4 samples at most), and that pixel is their colour to 8-bit rounding, a
    colour of the legend (whose rows are every second entry or so of the 256-colour map:
    within one entry)."""
    pixels = tendon_pixels(page, data, frame)
    taut = int((data["tendon_tension"][frame] > 0).sum())
    assert len(pixels) >= 2 / 3 * taut, f"{len(pixels)} of {taut} tendons seen clear of the others"
    legend = legend_colours(page)
    white = np.full(3, 255.0)
    exact = 0
    for j, found in pixels.items():
        colour = expected[j]
        alpha = ((found - white) @ (colour - white)) / max((colour - white) @ (colour - white), 1)
        blend = alpha[:, None] * colour + (1 - alpha[:, None]) * white
        assert np.abs(found - blend).max() <= 3 and alpha.min() >= 0.45, (
            f"tendon {j}: pixels {found.tolist()} are not its colour {colour} blended with white"
        )
        darkest = found[found.sum(axis=1).argmin()]
        if np.abs(darkest - colour).max() <= 2:
            exact += 1
            assert np.abs(legend - darkest).max(axis=1).min() <= 4, (j, darkest)
    assert exact >= 3 / 4 * len(pixels), f"{exact} of {len(pixels)} tendons in their colour"
    return pixels


def page_colours(data, value, low, high):
    """The colours (..., 3) (0..255) the page's colour map gives ``value`` on ``low .. high``:
    ``viewer.js``'s ``colorOf``, the legend's rule."""
    x = np.clip((np.asarray(value, dtype=float) - low) / (high - low), 0.0, 1.0)
    table = np.array(data["colormap"])
    return np.round(255 * table[np.round(x * (len(table) - 1)).astype(int)])


def test_drawn_tendons_have_the_legend_s_colours(page31):
    """The pixels of the tendons on the screen (not the colours the page meant to draw: issue
    27, where they were sRGB-encoded twice, (141, 15, 155) for the map's (68, 1, 84))."""
    page, data = page31
    tensions = np.where(data["tendon_tension"] > 0, data["tendon_tension"], np.inf)
    lowest = int(tensions.min(axis=1).argmin())  # the frame of the bottom of the colour map
    low, high = data["tension_range"]
    seen = []
    for frame in (0, lowest):  # 0: all taut, 30 to 99 N (the top of the map)
        page.call(f"tensegrityViewer.setFrame({frame})")
        expected = page_colours(data, data["tendon_tension"][frame], low, high)
        pixels = check_tendon_pixels(page, data, frame, expected)
        seen += [data["tendon_tension"][frame, j] for j in pixels]
    # the tendons seen span the map, from its first few colours to its last
    assert min(seen) < low + 0.02 * (high - low) and max(seen) > high - 1e-6 * high
    page.check_clean()


def test_hovering_a_member_names_it(page31):
    page, _ = page31
    page.call("tensegrityViewer.setFrame(0)")
    px, py, info = _member_under_pointer(page, np.linspace(0.3, 0.7, 9), np.linspace(0.3, 0.7, 9))
    page.page.mouse.move(px, py)
    page.page.wait_for_selector("#tip", state="visible")
    tip = page.page.inner_text("#tip")
    assert info["name"] in tip and "length" in tip and " m" in tip
    page.page.mouse.click(px, py)
    assert info["name"] in page.page.inner_text("#info")
    page.check_clean()


def load_clean(browser, tmp_path, what, **options):
    path = view(what, tmp_path / "view.html", **options)
    page = Page(browser, path)
    try:
        picture = page.picture()
        page.check_clean()
        assert drawn(picture).sum() > 500
        return page.call("tensegrityViewer.data.n_frames"), page
    finally:
        page.page.close()


def test_no_taut_tendon_loads_cleanly(browser, tmp_path):
    s = class1_shell(3, 1)
    loose = s.replace(tendon_rest_length=np.full(s.n_tendons, 3.0))
    run = simulate(loose, (0.0, 0.1), sample_dt=0.01)
    assert (run.tendon_tension <= 0).all()
    path = view(run, tmp_path / "loose.html")
    page = Page(browser, path)
    try:
        colours = [page.call(f"tensegrityViewer.tendonColor({j})") for j in range(24)]
        assert colours == [None] * 24  # every one drawn slack (dashed)
        assert "24 slack" in page.page.inner_text("#counts")
        assert drawn(page.picture()).sum() > 500
        page.check_clean()
    finally:
        page.page.close()


def test_planar_structure_loads_cleanly(browser, tmp_path):
    run = simulate(planar_two_rod(angle=1.1, rest_length=0.3), (0.0, 0.3), sample_dt=0.01)
    frames, _ = load_clean(browser, tmp_path, run)
    assert frames == run.t.size


def test_class2_shell_with_fixed_base_loads_cleanly(browser, tmp_path):
    shell = artificial_damping(class2_shell(4, 2, fixed_base=True))
    run = simulate(shell, (0.0, 0.1), sample_dt=0.01, gravity=[0, 0, -9.81])
    load_clean(browser, tmp_path, run)


def test_shell_30_30_loads_cleanly(browser, tmp_path):
    run = simulate(class1_shell(30, 30), (0.0, 0.02), sample_dt=0.01)
    frames, _ = load_clean(browser, tmp_path, run)
    assert frames == 3


def test_point_mass_between_anchors_loads_cleanly(browser, tmp_path):
    run = simulate(point_mass_between_anchors(), (0.0, 0.2), sample_dt=0.01)
    path = view(run, tmp_path / "mass.html")
    page = Page(browser, path)
    try:
        assert page.call("tensegrityViewer.tendonColor(0)") is not None
        assert drawn(page.picture()).sum() > 300
        page.check_clean()
    finally:
        page.page.close()


def test_the_notebook_view_runs_in_its_iframe(browser, tmp_path, shell31):
    path = tmp_path / "notebook.html"
    path.write_text(f"<!DOCTYPE html><html><body>{notebook_html(shell31)}</body></html>")
    page = Page(browser, path, viewer=False)
    try:
        page.page.frame_locator("iframe").locator("#clock").wait_for()
        inner = page.page.frames[1]
        inner.wait_for_function("window.tensegrityViewer && tensegrityViewer.ready")
        assert inner.evaluate("tensegrityViewer.nFrames") == 100  # the notebook's default
        assert "t = 0.000 s" in inner.inner_text("#clock")
        page.check_clean()
    finally:
        page.page.close()


def test_a_structure_page_loads_cleanly(browser, tmp_path):
    load_clean(browser, tmp_path, class2_shell(3, 2, fixed_base=True))


def test_a_mode_clip_without_energies_loads_cleanly(browser, tmp_path):
    """``tensegrity modes``' page: frames of ``plots.motion.motion_frames`` (no energies)."""
    from tensegrity.analysis.equilibrium import find_equilibrium
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import modal_analysis
    from tensegrity.cli.modes import mode_clip

    s = class1_shell(3, 1)
    modes = modal_analysis(linearize(s, find_equilibrium(s)))
    n_frames, _ = load_clean(browser, tmp_path, mode_clip(modes, int(modes.elastic_indices()[0])))
    assert n_frames == 48


def test_the_analysis_verbs_pages_load_cleanly(browser, tmp_path):
    """``tensegrity equilibrium``'s settling and ``tensegrity control``'s open- and closed-loop
    manoeuvres, as the verbs write them: drawn, no console error."""
    from tensegrity.cli.analysis import run_equilibrium
    from tensegrity.cli.control import run_control

    s = class1_shell(3, 1)
    run_equilibrium(s, method="simulation").write(tmp_path)
    run_control(s, steps=(4, 2)).write(tmp_path)
    for name in ("settling.html", "open_loop.html", "control.html"):
        page = Page(browser, tmp_path / name)
        try:
            picture = page.picture()
            page.check_clean()
            assert drawn(picture).sum() > 500, name
            assert page.call("tensegrityViewer.data.n_frames") >= 2, name
        finally:
            page.page.close()


def test_a_page_without_a_design_has_no_colour_mode(page31):
    page, data = page31
    assert "utilisation" not in data
    assert page.page.locator("#color-mode").count() == 0
    assert page.call("tensegrityViewer.utilisation(0)") is None
    assert page.call("tensegrityViewer.rodColor(0)") is None  # one material colour
    assert page.page.inner_text("#legend").startswith("tendon tension")
    assert "utilisation" not in page.page.inner_text("#legend")
    page.check_clean()


def test_a_designed_run_s_page_colours_members_by_utilisation(browser, tmp_path):
    run, check, _ = designed_prism()
    path = view(run, tmp_path / "designed.html", check=check, max_frames=16)
    data = read_viewer_data(path.read_text())
    u, high = data["utilisation"], data["utilisation"]["high"]
    page = Page(browser, path)
    try:
        frame = 10
        page.call(f"tensegrityViewer.setFrame({frame})")
        assert page.call("tensegrityViewer.colorMode()") == "tension"
        by_tension = page.picture()
        Image.fromarray(by_tension.astype(np.uint8)).save(tmp_path / "tension.png")
        page.page.select_option("#color-mode", "utilisation")  # the switch, as a user would
        assert page.call("tensegrityViewer.colorMode()") == "utilisation"
        by_use = page.picture()
        Image.fromarray(by_use.astype(np.uint8)).save(tmp_path / "utilisation.png")
        assert (np.abs(by_tension - by_use).max(axis=-1) > 60).sum() > 1000, "colours unchanged"
        assert page.page.inner_text("#legend").startswith("member utilisation")
        assert "utilisation > 1 (fails)" in page.page.inner_text("#legend")

        # the drawn colours: the page's rule, as the figures' (failing members: the failure colour)
        tendon, rod = u["tendons"][frame], u["rods"][frame]
        assert (tendon > 1).any() and (tendon <= 1).any() and (rod <= 1).all()
        drawn_tendons = [page.call(f"tensegrityViewer.tendonColor({j})") for j in range(9)]
        drawn_rods = [page.call(f"tensegrityViewer.rodColor({i})") for i in range(3)]
        np.testing.assert_allclose(
            drawn_tendons, utilisation_colors(tendon, high)[:, :3], atol=0.02
        )
        np.testing.assert_allclose(drawn_rods, utilisation_colors(rod, high)[:, :3], atol=0.02)
        failure = utilisation_colors(np.array([2.0]), high)[0, :3]
        for j in np.flatnonzero(tendon > 1):
            np.testing.assert_allclose(drawn_tendons[j], failure, atol=1e-6)
        # and on the screen: safe tendons on the map, failing ones in the failure colour
        expected = np.where(
            (tendon > 1)[:, None], np.round(255 * failure), page_colours(data, tendon, 0, high)
        )
        seen = check_tendon_pixels(page, data, frame, expected)
        assert any(tendon[j] > 1 for j in seen) and any(tendon[j] <= 1 for j in seen)

        # hovering a member shows its utilisation
        px, py, info = _member_under_pointer(
            page, np.linspace(0.35, 0.65, 13), np.linspace(0.2, 0.6, 17)
        )
        expected = (u["rods"] if info["kind"] == "rod" else u["tendons"])[frame][info["id"]]
        assert info["utilisation"] == pytest.approx(float(expected), rel=1e-7)
        page.page.mouse.move(px, py)
        page.page.wait_for_selector("#tip", state="visible")
        assert f"utilisation {float(expected):.4g}"[:15] in page.page.inner_text("#tip")

        canvas = page.page.locator("#view canvas").bounding_box()
        page.page.mouse.move(canvas["x"] + 5, canvas["y"] + 5)  # (nothing there: no tip)
        page.page.wait_for_selector("#tip", state="hidden")
        # and back: tension colours, rods in the rod colour
        page.call("tensegrityViewer.setColorMode('tension')")
        assert page.page.input_value("#color-mode") == "tension"
        low, top = data["tension_range"]
        tension = data["tendon_tension"][frame].astype(float)
        np.testing.assert_allclose(
            [page.call(f"tensegrityViewer.tendonColor({j})") for j in range(9)],
            tension_colormap()((tension - low) / (top - low))[:, :3],
            atol=0.02,
        )
        check_tendon_pixels(page, data, frame, page_colours(data, tension, low, top))
        rod_colour = page.call("tensegrityViewer.rodColor(0)")
        np.testing.assert_allclose(rod_colour, to_rgb(ROD_COLOR), atol=1e-3)
        assert np.abs(page.picture() - by_tension).max() < 60
        page.check_clean()
    finally:
        page.page.close()


def test_a_run_on_the_ground_shows_the_plane_and_its_ends_by_mode(browser, tmp_path):
    """Issue 29: the plane's patch drawn semi-transparent under the robot, the ends in contact
    marked in their mode's colour at each frame (the run's modes, as the page holds them), and
    the legend's key."""
    from tensegrity.model.ground import SLIP, STICK
    from tensegrity.plots.figures import PLANE_ALPHA, PLANE_COLOR, SLIP_COLOR, STICK_COLOR
    from test_contact_view import SCENE, sliding_robot

    run = simulate(sliding_robot(), (0.0, 0.3), sample_dt=0.01, **SCENE.simulate_options())
    path = view(run, tmp_path / "ground.html")
    data = read_viewer_data(path.read_text())
    modes = data["contacts"]["mode"]
    page = Page(browser, path)
    try:
        assert "plane" in page.page.inner_text("#legend")
        assert "sticking" in page.page.inner_text("#legend")
        plane = np.array(to_rgb(PLANE_COLOR)) * 255 * PLANE_ALPHA + 255 * (1 - PLANE_ALPHA)
        canvas = page.page.locator("#view canvas").bounding_box()
        for mode, color in ((STICK, STICK_COLOR), (SLIP, SLIP_COLOR)):
            k = int(np.flatnonzero((modes == mode).any(axis=1))[0])
            page.call(f"tensegrityViewer.setFrame({k})")
            assert page.call(f"tensegrityViewer.contactModes({k})") == modes[k].tolist()
            ends = page.call("tensegrityViewer.contactEnds()")
            nodes = np.unique(run.contact_node[modes[k] == mode])
            marked = [n for n, m in zip(ends["node"], ends["mode"], strict=True) if m == mode]
            assert marked == nodes.tolist()
            picture = page.picture()
            on_plane = np.all(np.abs(picture - plane) <= 3, axis=-1)
            assert on_plane.mean() > 0.05
            lowest = max(
                page.call(f"tensegrityViewer.toScreen({x}, {y}, {z})")[1]
                for x, y, z in data["node_position"][k]
            )
            assert np.flatnonzero(on_plane.any(axis=1)).max() > lowest - canvas["y"] + 10
            rgb = np.array(to_rgb(color)) * 255
            for n in nodes:
                x, y, z = data["node_position"][k][n]
                px, py = page.call(f"tensegrityViewer.toScreen({x}, {y}, {z})")
                column, row = round(px - canvas["x"]), round(py - canvas["y"])
                near = picture[row - 2 : row + 3, column - 2 : column + 3]
                assert np.all(np.abs(near - rgb) <= 40, axis=-1).sum() >= 5
        page.check_clean()
    finally:
        page.page.close()
