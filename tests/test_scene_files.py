"""The scene in structure files (issue 29): a file carries its planes, contact radius and
gravity (``scene``), read back equal, checked with one-line errors naming the key, used by
``tensegrity simulate --structure`` unless the ground options override it, and written with the
run's structure."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from tensegrity.design.catalogue import six_bar_robot, three_bar_robot
from tensegrity.design.files import read_design, write_design
from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.io.formats import read_network, read_scene, write_network
from tensegrity.model.ground import Plane, Scene, ground

SCENE = Scene(
    (
        ground(-0.5, friction=0.8, kinetic_friction=0.6, stiffness=2e5, damping=50.0),
        Plane(point=(2.0, 0.0, 0.0), normal=(-1.0, 0.3, 0.2), friction=0.4),
    ),
    0.01,
    (0.0, 0.0, -9.81),
)


def _fields(scene: Scene) -> list[dict]:
    return [plane.settings() for plane in scene.planes]


@pytest.mark.parametrize("suffix", [".json", ".yaml", ".toml"])
def test_a_scene_written_with_a_structure_reads_back_equal(tmp_path, suffix):
    robot = three_bar_robot()
    path = write_network(tmp_path / f"robot{suffix}", robot, scene=SCENE)
    scene = read_scene(path)
    assert _fields(scene) == _fields(SCENE)
    assert scene.contact_radius == 0.01 and np.array_equal(scene.gravity, SCENE.gravity)
    assert scene == SCENE
    assert read_network(path).to_dict() == robot.to_dict()  # (the structure as before)


def test_the_readable_form_as_json_and_the_material_form_carry_a_scene(tmp_path):
    robot = three_bar_robot()
    design = MemberDesign.of(
        robot,
        rod_material=material("steel"),
        rod_section=SolidRod(0.02),
        tendon_material=material("steel"),
        tendon_section=Cable(0.003),
    )
    built = design.apply(robot)
    path = write_design(tmp_path / "robot.json", built, design, scene=SCENE)
    assert json.loads(path.read_text())["format"] == "tensegrity-network"
    assert read_scene(path) == SCENE
    assert read_design(path).structure.to_dict() == built.to_dict()


def test_a_file_without_a_scene_has_an_empty_one(tmp_path):
    for name in ("a.json", "a.yaml", "a.npz"):
        path = write_network(tmp_path / name, three_bar_robot())
        assert read_scene(path) == Scene() and read_scene(path).simulate_options()["ground"] is None
    assert "scene" not in json.loads((tmp_path / "a.json").read_text())
    with pytest.raises(ValueError, match=r"^scene: the connectivity form"):
        write_network(tmp_path / "b.npz", three_bar_robot(), scene=SCENE)


@settings(max_examples=60, deadline=None)
@given(
    normal=st.tuples(*[st.floats(-10, 10)] * 3).filter(lambda n: np.linalg.norm(n) > 1e-3),
    height=st.floats(-1e3, 1e3),
    friction=st.floats(0, 5),
    ratio=st.floats(0, 1),
    radius=st.floats(0, 1),
)
def test_any_plane_reads_back_bit_for_bit(
    tmp_path_factory, normal, height, friction, ratio, radius
):
    """A plane's normal is normalized when it is made: made again from its written fields (a
    file read back) it is the same, bit for bit."""
    plane = Plane(point=(0.0, 0.0, height), normal=normal, friction=friction,
                  kinetic_friction=friction * ratio)  # fmt: skip
    scene = Scene((plane,), radius)
    path = write_network(tmp_path_factory.mktemp("s") / "s.json", three_bar_robot(), scene=scene)
    assert _fields(read_scene(path)) == _fields(scene)


@pytest.mark.parametrize(
    ("planes", "words"),
    [
        ([{"normal": [0, 0, 0]}], r"scene\.planes\[0\]\.normal: must not be zero"),
        ([{}, {"friction": -0.1}], r"scene\.planes\[1\]\.friction: must be a finite number >= 0"),
        ([{"stiffness": "stiff"}], r"planes\[0\]\.stiffness: expected a number, got 'stiff'"),
        ([{"point": [0, "x", 0]}], r"scene\.planes\[0\]\.point\[1\]: expected a number"),
        ([{"friction": 0.2, "kinetic_friction": 0.3}], r"kinetic_friction: must not exceed"),
        ([{"frcition": 0.2}], r"scene\.planes\[0\]: unknown key 'frcition'"),
    ],
)
@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_a_bad_scene_is_one_line_naming_the_file_and_the_field(tmp_path, planes, words, suffix):
    path = write_network(tmp_path / f"robot{suffix}", three_bar_robot(), scene=SCENE)
    if suffix == ".json":
        data = json.loads(path.read_text())
        data["scene"]["planes"] = planes
        path.write_text(json.dumps(data))
    else:
        import yaml

        data = yaml.safe_load(path.read_text())
        data["scene"]["planes"] = planes
        path.write_text(yaml.safe_dump(data))
    for reader in (read_scene, read_network):  # (the structure readers check it too)
        with pytest.raises(ValueError) as info:
            reader(path)
        message = str(info.value)
        assert len(message.splitlines()) == 1 and message.startswith(str(path)), message
        assert re.search(words, message), message


def test_a_bad_radius_or_gravity_names_the_key(tmp_path):
    path = write_network(tmp_path / "robot.yaml", three_bar_robot(), scene=SCENE)
    text = path.read_text()
    for old, new, words in (
        ("contact_radius: 0.01", "contact_radius: -1", r"scene\.contact_radius: must be"),
        ("gravity: [0.0, 0.0, -9.81]", "gravity: [0, -9.81]", r"scene\.gravity: expected a list"),
        ("gravity: [0.0, 0.0, -9.81]", "gravity: down", r"scene\.gravity: expected a number"),
    ):
        assert old in text
        path.write_text(text.replace(old, new))
        with pytest.raises(ValueError, match=words):
            read_scene(path)


# ------------------------------------------------------------------------------ the command
def _robot_file(tmp_path, scene: Scene = SCENE):
    """The six-bar robot of ``test_contact``'s command test, its lowest ends on ``z = -0.5``,
    in a YAML file with ``scene``."""
    from tensegrity.physics.dynamics import internal_damping

    robot = internal_damping(six_bar_robot(stiffness=2000.0, tension=100.0))
    nodes = robot.node_position.copy()
    nodes[:, 2] += -0.5 - nodes[:, 2].min()
    return write_network(tmp_path / "robot.yaml", robot.replace(node_position=nodes), scene=scene)


RUN = ["--t-end", "1", "--no-view", "--no-animation"]


def test_the_simulate_command_uses_the_file_s_scene_and_writes_it_back(tmp_path, capsys):
    """``simulate --structure robot.yaml`` with no ground options: the robot stands on the
    file's plane under the file's gravity (no end's centre below the plane by its radius or
    more), and ``OUT/structure.json`` carries that scene, so a second run has it again."""
    from tensegrity.cli.main import main
    from tensegrity.io.trajectory import read_trajectory

    scene = Scene(SCENE.planes[:1], SCENE.contact_radius, SCENE.gravity)
    out = tmp_path / "out"
    assert main(["simulate", "--structure", str(_robot_file(tmp_path, scene)), *RUN,
                 "--out", str(out)]) == 0  # fmt: skip
    assert "contacts" in capsys.readouterr().out
    run = read_trajectory(out / "trajectory.h5")
    assert run.settings["ground"] == _fields(scene)
    assert run.settings["contact_radius"] == 0.01
    lowest = run.node_position[:, :, 2].min(axis=1)
    assert lowest.min() > -0.5 - 0.01  # (the plane holds it: without it, it falls)
    assert -0.5 < lowest[-1] < -0.49  # (resting on it: the file's gravity holds it there)
    assert read_scene(out / "structure.json") == scene


def test_the_ground_options_override_the_file_s_scene(tmp_path):
    """``--ground`` replaces the file's planes, ``--friction`` alone changes theirs,
    ``--contact-radius`` and ``--gravity`` replace the file's own."""
    from tensegrity.cli.main import main
    from tensegrity.io.trajectory import read_trajectory

    path = _robot_file(tmp_path)
    short = ["--t-end", "0.02", "--no-view", "--no-animation", "--no-steady-state"]
    assert main(["simulate", "--structure", str(path), *short, "--ground", "-0.6",
                 "--contact-radius", "0.02", "--gravity", "3", "--out",
                 str(tmp_path / "a")]) == 0  # fmt: skip
    run = read_trajectory(tmp_path / "a" / "trajectory.h5")
    assert run.settings["ground"] == [ground(-0.6).settings()]
    assert run.settings["contact_radius"] == 0.02
    assert read_scene(tmp_path / "a" / "structure.json") == Scene((ground(-0.6),), 0.02, (0, 0, -3))
    assert main(["simulate", "--structure", str(path), *short, "--friction", "0.3",
                 "--out", str(tmp_path / "b")]) == 0  # fmt: skip
    planes = read_trajectory(tmp_path / "b" / "trajectory.h5").settings["ground"]
    assert [(p["friction"], p["kinetic_friction"]) for p in planes] == [(0.3, 0.3)] * 2
    assert [p["normal"] for p in planes] == [p.normal.tolist() for p in SCENE.planes]


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--ground-normal", "0,1,1"], "--ground-normal: only with --ground"),
        (["--friction", "-1"], "--friction: must be a finite number >= 0"),
        (["--contact-damping", "-3"], "--contact-damping: must be a finite number >= 0"),
    ],
)
def test_a_ground_option_that_cannot_apply_to_the_file_s_planes(tmp_path, capsys, argv, words):
    from tensegrity.cli.main import main

    path = _robot_file(tmp_path)
    code = main(["simulate", "--structure", str(path), *argv, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and words in err, err
    assert not (tmp_path / "o").exists()


def test_friction_without_any_plane_is_refused(tmp_path, capsys):
    from tensegrity.cli.main import main

    code = main(["simulate", "--kind", "three-bar", "--friction", "0.3", "--out",
                 str(tmp_path / "o")])  # fmt: skip
    err = capsys.readouterr().err.strip()
    assert code == 2 and "--friction: needs --ground, or a --structure file with planes" in err


def test_a_bad_scene_in_the_structure_file_names_the_option_the_file_and_the_key(tmp_path, capsys):
    from tensegrity.cli.main import main

    path = _robot_file(tmp_path)
    path.write_text(path.read_text().replace("normal: [0.0, 0.0, 1.0]", "normal: [0, 0, 0]"))
    code = main(["simulate", "--structure", str(path), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert f"--structure: {path}: scene.planes[0].normal: must not be zero" in err, err
