"""Untrusted input files (docs/reliability.md): every reader refuses, with a one-line
``ValueError`` naming the file and the dataset or attribute, what is not the documented layout
(HDF5 external storage, external, soft and virtual links out of the file, compound, complex and
other non-float dtypes, attributes of the wrong type or shape), and anything over its limits
(devices and FIFOs, files and arrays larger than ``TENSEGRITY_MAX_INPUT_BYTES`` and
``TENSEGRITY_MAX_ARRAY_BYTES``), before reading the data.

The cases that would exhaust the machine on a regression (a file or array of gigabytes, a FIFO
that never ends) run in a child process under a cap on its address space (``RLIMIT_AS``) and a
timeout: a regression fails the test (a ``MemoryError`` traceback, or the timeout) instead of
the machine.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import zipfile
import zlib
from pathlib import Path

import h5py
import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.io.files import file_error
from tensegrity.io.formats import read_network, read_structure, write_network
from tensegrity.io.stream import PARTIAL_SUFFIX, StreamProgress, read_checkpoint, simulate_to_file
from tensegrity.io.trajectory import read_dataset, read_trajectory, write_trajectory

GiB = 2**30
#: Address space of a child process [bytes]: the interpreter with numpy, h5py and numba loaded
#: takes about 0.45 GiB; every crafted file asks for more than the rest.
MEMORY_CAP = GiB
#: Seconds a child process may take (it takes about 2 s; a FIFO read on would block forever).
TIMEOUT = 30
#: Exit code of a child process that caught a ``ValueError`` (printed to stdout).
REFUSED = 3

CHILD = """
import sys
from tensegrity.io.formats import read_network, read_structure
from tensegrity.io.stream import read_checkpoint
from tensegrity.io.tables import read_force_table
from tensegrity.io.trajectory import read_dataset, read_trajectory
from tensegrity.sweep import SweepSpec, read_sweep
path = sys.argv[1]
try:
    {call}
except ValueError as exc:
    print(exc)
    sys.exit({refused})
"""


def _capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def run_capped(call: str, path: Path, **env: str) -> str:
    """Run ``call`` (Python, on ``path``) in a child process under the memory cap and timeout;
    return the one-line message of the ``ValueError`` it must raise."""
    environment = {
        **os.environ,
        "OPENBLAS_NUM_THREADS": "1",
        "OMP_NUM_THREADS": "1",
        "NUMBA_NUM_THREADS": "1",
        **env,
    }
    try:
        child = subprocess.run(
            [sys.executable, "-c", CHILD.format(call=call, refused=REFUSED), str(path)],
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            env=environment,
            preexec_fn=_capped,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"{call} on {path} still running after {TIMEOUT} s")
    assert child.returncode == REFUSED, (
        f"{call}: exit {child.returncode}\n{child.stdout}\n{child.stderr[-3000:]}"
    )
    return child.stdout.rstrip("\n")


def assert_one_line(message: str, path: Path, *words: str) -> None:
    assert "\n" not in message, message
    assert message.startswith(f"{path}: "), message
    for word in words:
        assert word in message, (word, message)


def assert_refused(read, path: Path, *words: str) -> None:
    with pytest.raises(ValueError) as info:
        read(path)
    assert_one_line(str(info.value), path, *words)


# ------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def result():
    """A short damped (3,1) shell run: 3 samples, 12 nodes, 24 tendons, 36 coordinates."""
    return simulate(artificial_damping(class1_shell(3, 1)), (0.0, 0.1), sample_dt=0.05)


@pytest.fixture
def secret(tmp_path):
    """A local file a crafted trajectory points at, and an HDF5 file with a dataset of it."""
    path = tmp_path / "secret.txt"
    path.write_bytes(b"password=hunter2;" * 256)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["data"] = np.frombuffer(path.read_bytes()[: 3 * 12 * 3 * 8], dtype="<f8").reshape(
            3, 12, 3
        )
    return path, other


def crafted(tmp_path: Path, result, edit) -> Path:
    """A trajectory written by the library, then changed by ``edit(file)``."""
    path = tmp_path / "crafted.h5"
    write_trajectory(path, result)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


def replace(f, name: str, **dataset) -> None:
    del f[name]
    f.create_dataset(name, **dataset)


# ------------------------------------------------------------------ not the documented layout
def _external_storage(f, secret, other):
    replace(f, "q", shape=(3, 36), dtype="<f8", external=[(str(secret), 0, 864)])


def _external_link(f, secret, other):
    del f["q"]
    f["q"] = h5py.ExternalLink(str(other), "/data")


def _soft_link_out(f, secret, other):
    f["elsewhere"] = h5py.ExternalLink(str(other), "/data")
    del f["q"]
    f["q"] = h5py.SoftLink("/elsewhere")


def _virtual(f, secret, other):
    layout = h5py.VirtualLayout(shape=(3, 36), dtype="<f8")
    layout[:, :12] = h5py.VirtualSource(str(other), "data", shape=(3, 12, 3))[:, :, 0]
    del f["q"]
    f.create_virtual_dataset("q", layout)


def _complex(f, secret, other):
    replace(f, "q", data=np.zeros((3, 36), complex))


def _compound(f, secret, other):
    replace(f, "t", data=np.zeros(3, dtype=[("t", "<f8"), ("u", "<f8")]))


def _text(f, secret, other):
    replace(
        f, "tendon_tension", data=np.full((3, 24), "1.0", dtype=object), dtype=h5py.string_dtype()
    )


def _integer(f, secret, other):
    replace(f, "q", data=np.zeros((3, 36), np.int64))


@pytest.mark.parametrize(
    "edit, name, words",
    [
        (_external_storage, "q", ["external storage"]),
        (_external_link, "q", ["external link"]),
        (_soft_link_out, "q", ["soft link"]),
        (_virtual, "q", ["virtual"]),
        (_complex, "q", ["complex"]),
        (_compound, "t", ["compound"]),
        (_text, "tendon_tension", ["floating-point"]),
        (_integer, "q", ["floating-point", "int64"]),
    ],
)
def test_trajectory_datasets_outside_the_layout_are_refused(
    tmp_path, result, secret, edit, name, words
):
    """Refused by both readers with the dataset named, before any of its data is read."""
    path = crafted(tmp_path, result, lambda f: edit(f, *secret))
    assert_refused(read_trajectory, path, f"dataset {name!r}", *words)
    assert_refused(lambda p: read_dataset(p, name), path, f"dataset {name!r}", *words)


def test_names_in_messages_are_one_line_with_control_characters_escaped(tmp_path, result, secret):
    """A file name with a newline or a terminal escape, given to a reader or stored in a crafted
    file as the target of an external link, shows in the message escaped as in a Python string
    (``\\n``, ``\\x1b``): one line, no escape sequence for the terminal."""
    odd = tmp_path / "two\nlines\x1b[2J.json"
    assert str(file_error(odd, "no such file")) == (
        f"{tmp_path}/two\\nlines\\x1b[2J.json: no such file"
    )
    with pytest.raises(ValueError) as info:
        read_structure(odd)
    assert str(info.value) == f"{tmp_path}/two\\nlines\\x1b[2J.json: no such file"

    def link(f):
        del f["q"]
        f["q"] = h5py.ExternalLink(f"{secret[1]}\n\x1b[2J", "/data")

    path = crafted(tmp_path, result, link)
    with pytest.raises(ValueError) as info:
        read_trajectory(path)
    assert_one_line(str(info.value), path, f"(to {secret[1]}\\n\\x1b[2J:/data)")
    assert "\x1b" not in str(info.value)


def test_a_torn_copy_is_refused_in_one_line(tmp_path, result):
    """A file copied while it was written (its superblock from before the write, a dataset
    rewritten past the end the superblock records): h5py raised a ``KeyError`` ("address of
    object past end of allocation") from the checks themselves; now one line naming the file and
    the dataset.  (``tests/test_cli_resume.py`` reads such copies of a running partial file.)"""
    before = write_trajectory(tmp_path / "before.h5", result).read_bytes()
    path = crafted(tmp_path, result, lambda f: replace(f, "q", data=np.zeros((3, 36))))
    path.write_bytes(before[:48] + path.read_bytes()[48:])  # the superblock of before the write
    for read in (read_trajectory, lambda p: read_dataset(p, "q")):
        assert_refused(read, path, "dataset 'q'", "damaged")


def test_vtk_command_does_not_copy_local_files_into_its_output(tmp_path, result, secret, capsys):
    """``tensegrity vtk`` on a trajectory whose coordinates are stored in another local file: one
    line, exit 2, and no ``.vtp`` file carrying that file's bytes."""
    path = crafted(tmp_path, result, lambda f: _external_storage(f, *secret))
    out = tmp_path / "vtk"
    assert main(["vtk", str(path), "-o", str(out)]) == 2
    error = capsys.readouterr().err.strip()
    assert "\n" not in error and str(path) in error and "'q'" in error, error
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda f: f.attrs.__setitem__("version", np.inf), ["attribute 'version'"]),
        (lambda f: f.attrs.__setitem__("status", np.inf), ["attribute 'status'"]),
        (lambda f: f.attrs.__setitem__("status", np.array([0, 0])), ["attribute 'status'"]),
        (lambda f: f.attrs.__setitem__("nfev", "many"), ["attribute 'nfev'"]),
        (lambda f: f.attrs.__setitem__("wall_time", 1 + 2j), ["attribute 'wall_time'"]),
        (lambda f: f.attrs.__setitem__("message", 5), ["attribute 'message'", "text"]),
        (lambda f: f.attrs.__setitem__("structure", np.bytes_(b"\xff{")), ["'structure'", "UTF-8"]),
        (lambda f: f.attrs.__setitem__("settings", "[" * 100_000), ["attribute 'settings'"]),
        (lambda f: f.attrs.__setitem__("settings", "[1, 2]"), ["attribute 'settings'", "object"]),
        (lambda f: f["energy"].attrs.__setitem__("columns", 5), ["'columns'"]),
    ],
)
def test_trajectory_attributes_of_the_wrong_type_or_shape_are_refused(
    tmp_path, result, edit, words
):
    assert_refused(read_trajectory, crafted(tmp_path, result, edit), *words)


# ---------------------------------------------------------------- .npz arrays of a structure
def _network_arrays(tmp_path: Path) -> dict[str, np.ndarray]:
    """The arrays of the (3,1) shell's connectivity file, with a node on a plane and one on a
    line."""
    path = write_network(tmp_path / "shell.npz", class1_shell(3, 1))
    with np.load(path) as archive:
        arrays = {name: archive[name] for name in archive.files}
    arrays |= dict(plane_nodes=np.array([0]), plane_normal=np.array([[0.0, 0.0, 1.0]]))
    arrays |= dict(line_nodes=np.array([1]), line_direction=np.array([[1.0, 0.0, 0.0]]))
    return arrays


def _saved(tmp_path: Path, arrays: dict[str, np.ndarray]) -> Path:
    path = tmp_path / "crafted.npz"
    np.savez(path, **arrays)
    return path


REAL_ARRAYS = ["N", "C_b", "C_s", "node_velocity", "rod_mass", "rod_length", "rod_damping"]
REAL_ARRAYS += ["tendon_stiffness", "tendon_rest_length", "tendon_damping"]
REAL_ARRAYS += ["plane_normal", "line_direction"]


@pytest.mark.parametrize(
    "dtype, words", [(complex, "complex numbers"), (bool, "bool"), ("<U24", "text")]
)
@pytest.mark.parametrize("name", REAL_ARRAYS)
def test_npz_arrays_of_numbers_refuse_complex_booleans_and_text(tmp_path, name, dtype, words):
    """Complex numbers where real ones belong were read with a ComplexWarning and their
    imaginary parts dropped; booleans and text (numpy parses "1.5") were read as numbers.  Each
    is refused naming the array, as the HDF5 readers refuse them."""
    arrays = _network_arrays(tmp_path)
    arrays[name] = arrays[name].astype(dtype)
    path = _saved(tmp_path, arrays)
    assert_refused(read_network, path, f"array {name!r}: expected real numbers", words)


@pytest.mark.parametrize(
    "value, words",
    [
        (np.array([0.5]), "whole numbers, got 0.5"),
        (np.array([np.nan]), "whole numbers, got nan"),
        (np.array([0j]), "expected node indices, got complex numbers"),
        (np.array([True]), "expected node indices, got bool"),
        (np.array(["0"]), "expected node indices, got text"),
    ],
)
@pytest.mark.parametrize("name", ["plane_nodes", "line_nodes", "joint_nodes"])
def test_npz_node_indices_refuse_fractions_complex_booleans_and_text(tmp_path, name, value, words):
    """A node index array of fractions, complex numbers, booleans or text is refused naming the
    array (before: booleans were taken as indices 0 and 1, complex numbers and text failed on
    numpy's "ufunc 'remainder' not supported" naming nothing, fractions on "expected a list of
    node indices, got shape (1,)")."""
    arrays = _network_arrays(tmp_path)
    arrays[name] = value.reshape(1, 1).repeat(2, axis=1) if name == "joint_nodes" else value
    assert_refused(read_network, _saved(tmp_path, arrays), f"array {name!r}", words)


def test_npz_other_arrays_refuse_other_kinds(tmp_path):
    """Tendon names must be text (numbers were read as the names "0", "1", ...), the fixed
    nodes booleans."""
    arrays = _network_arrays(tmp_path)
    arrays["tendon_name"] = np.arange(arrays["tendon_name"].size)
    path = _saved(tmp_path, arrays)
    assert_refused(read_network, path, "array 'tendon_name': expected text, got int64")
    arrays = _network_arrays(tmp_path)
    arrays["node_fixed"] = np.zeros(12)
    path = _saved(tmp_path, arrays)
    assert_refused(read_network, path, "array 'node_fixed': expected booleans, got float64")


def test_npz_integers_for_numbers_and_whole_floats_for_indices_are_read(tmp_path):
    """What is refused is the kind of data, not its width: integer node positions and masses,
    and node indices written as floats of whole numbers, read as the same structure."""
    arrays = _network_arrays(tmp_path)
    expected = read_network(_saved(tmp_path, arrays))
    arrays["rod_mass"] = arrays["rod_mass"].astype(np.int32)
    arrays["C_b"] = arrays["C_b"].astype(np.float32)
    arrays["plane_nodes"] = arrays["plane_nodes"].astype(float)
    arrays["line_nodes"] = arrays["line_nodes"].astype(np.uint8)
    assert read_network(_saved(tmp_path, arrays)).to_dict() == expected.to_dict()


# ---------------------------------------------------------------------- sweep datasets
@pytest.fixture(scope="module")
def sweep_file(tmp_path_factory):
    """A sweep of four (3,1) and (4,1) shells, three samples each, saved by the library."""
    pytest.importorskip("distributed")
    pytest.importorskip("xarray")
    from distributed import Client, LocalCluster

    from tensegrity.sweep import SweepSpec, run_sweep

    spec = SweepSpec({"stiffness": [100.0, 200.0], "n": [3, 4]}, t_end=0.004, sample_dt=0.002)
    with (
        LocalCluster(
            n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        result = run_sweep(spec, client=client)
    return result.save(tmp_path_factory.mktemp("sweep") / "sweep.nc")


def crafted_sweep(tmp_path: Path, sweep_file: Path, edit) -> Path:
    """A sweep file written by the library, then changed by ``edit(file)``."""
    path = tmp_path / "crafted.nc"
    path.write_bytes(sweep_file.read_bytes())
    with h5py.File(path, "a") as f:
        edit(f)
    return path


def replace_variable(f, name: str, **dataset) -> None:
    """Replace the sweep's variable ``name`` by ``f.create_dataset(name, **dataset)`` (the old
    shape, and the dtype of the data or the old one, unless given), with the old one's
    attributes and dimensions: xarray reads it as one of the sweep's variables."""
    old = f[name]
    dtype = dataset["data"].dtype if "data" in dataset else old.dtype
    dataset = {"shape": old.shape, "dtype": dtype, **dataset}
    drop = ("DIMENSION_LIST", "_FillValue")  # (the fill value is of the old dtype)
    attrs = {key: value for key, value in old.attrs.items() if key not in drop}
    scales = [old.dims[i][0] for i in range(old.ndim)]
    for i, scale in enumerate(scales):
        old.dims[i].detach_scale(scale)
    del f[name]
    new = f.create_dataset(name, **dataset)
    new.attrs.update(attrs)
    for i, scale in enumerate(scales):
        new.dims[i].attach_scale(scale)


def _sweep_external_storage(f, secret, other):
    replace_variable(f, "max_tension", external=[(str(secret), 0, 8 * f["max_tension"].size)])


def _sweep_external_link(f, secret, other):
    del f["max_tension"]
    f["max_tension"] = h5py.ExternalLink(str(other), "/data")


def _sweep_soft_link(f, secret, other):
    del f["max_tension"]
    f["max_tension"] = h5py.SoftLink("/wall_time")


def _sweep_virtual(f, secret, other):
    layout = h5py.VirtualLayout(shape=f["max_tension"].shape, dtype="<f8")
    source = h5py.VirtualSource(str(other), "data", shape=(3, 12, 3))
    layout[...] = source[0, : layout.shape[0], : layout.shape[1]]
    del f["max_tension"]
    f.create_virtual_dataset("max_tension", layout)


def _sweep_group(f, secret, other):
    f.create_group("extra").create_dataset("data", data=np.zeros(3))


@pytest.mark.parametrize(
    "edit, words",
    [
        (_sweep_external_storage, ["dataset 'max_tension'", "external storage"]),
        (_sweep_external_link, ["dataset 'max_tension'", "external link"]),
        (_sweep_soft_link, ["dataset 'max_tension'", "soft link"]),
        (_sweep_virtual, ["dataset 'max_tension'", "virtual"]),
        (lambda f, *_: replace_variable(f, "max_tension", dtype=complex), ["complex"]),
        (
            lambda f, *_: replace_variable(f, "max_tension", dtype=np.int64),
            ["dataset 'max_tension'", "floating-point", "int64"],
        ),
        (
            lambda f, *_: replace_variable(
                f, "t_final", data=np.full(4, "1.0", dtype=object), dtype=h5py.string_dtype()
            ),
            ["dataset 't_final'", "floating-point", "text"],
        ),
        (
            lambda f, *_: replace_variable(f, "message", data=np.zeros(4)),
            ["dataset 'message'", "expected text"],
        ),
        (
            lambda f, *_: replace_variable(
                f, "wall_time", data=np.zeros(4, dtype=[("t", "<f8"), ("u", "<f8")])
            ),
            ["dataset 'wall_time'", "compound"],
        ),
        (_sweep_group, ["'extra' is not a dataset"]),
        (lambda f, *_: f.attrs.__delitem__("spec"), ["missing attribute 'spec'"]),
        (lambda f, *_: f.attrs.__setitem__("spec", 5), ["attribute 'spec'", "text"]),
        (lambda f, *_: f.attrs.__setitem__("spec", "[1, 2]"), ["attribute 'spec'", "object"]),
    ],
)
def test_sweep_outside_the_layout_is_refused(tmp_path, sweep_file, secret, edit, words):
    """``read_sweep`` checks the file as the other readers do before xarray reads it (before:
    xarray read whatever the file held: the secret file through external storage, complex
    and text data, links out of the file)."""
    from tensegrity.sweep import read_sweep

    path = crafted_sweep(tmp_path, sweep_file, lambda f: edit(f, *secret))
    assert_refused(read_sweep, path, *words)


def test_sweep_reads_the_dataset_it_was_saved_with(sweep_file):
    import xarray as xr

    from tensegrity.sweep import read_sweep

    dataset = read_sweep(sweep_file)
    with xr.open_dataset(sweep_file, engine="h5netcdf") as direct:
        assert dataset.identical(direct)
    assert dataset.sizes == {"case": 4, "t": 3}


def test_sweep_arrays_and_attributes_count_against_the_limit(tmp_path, sweep_file, monkeypatch):
    """The sweep's arrays and every attribute count against ``TENSEGRITY_MAX_ARRAY_BYTES``."""
    from tensegrity.sweep import read_sweep

    monkeypatch.setenv("TENSEGRITY_MAX_ARRAY_BYTES", "100")
    assert_refused(read_sweep, sweep_file, "TENSEGRITY_MAX_ARRAY_BYTES=100")
    monkeypatch.setenv("TENSEGRITY_MAX_ARRAY_BYTES", str(2**15))
    read_sweep(sweep_file)
    path = crafted_sweep(
        tmp_path, sweep_file, lambda f: f["stiffness"].attrs.__setitem__("note", np.zeros(5000))
    )
    assert_refused(read_sweep, path, "attribute 'note' of 'stiffness'", "TENSEGRITY_MAX_ARRAY")


def test_a_torn_copy_of_a_sweep_is_refused_in_one_line(tmp_path, sweep_file):
    """A sweep file copied while it was written: the superblock from before the write, the
    root group grown past the end it records (as the torn checkpoint below): one line naming
    the file and the group, not h5py's bare ``RuntimeError``."""
    from tensegrity.sweep import read_sweep

    path = crafted_sweep(tmp_path, sweep_file, lambda f: None)
    before = path.read_bytes()
    with h5py.File(path, "a") as f:
        for i in range(40):  # past the compact link storage: a new heap at the end of the file
            f[f"extra{i}"] = np.zeros(3)
    path.write_bytes(before[:48] + path.read_bytes()[48:])
    assert_refused(read_sweep, path, "group '/'", "damaged")


def test_sweep_not_hdf5_is_refused(tmp_path):
    from tensegrity.sweep import read_sweep

    path = tmp_path / "sweep.nc"
    path.write_text("case,stiffness\n0,100\n")
    assert_refused(read_sweep, path, "not an HDF5 file")


def _huge_sweep_variable(f):
    """A variable of its own dimension whose shape asks for 7 GiB (no data stored)."""
    f.create_dataset("huge", shape=(7 * GiB // 8,), dtype="<f8", chunks=(2**16,))
    f["huge"].make_scale("huge")


def _sweep_chunk_bomb(f):
    """Three samples in one chunk of 2 GiB (9 MiB on disk, compressed)."""
    rows = 2**28
    deflate = zlib.compressobj(1)
    block = bytes(2**20)
    data = b"".join(deflate.compress(block) for _ in range(8 * rows // len(block)))
    data += deflate.flush()
    bomb = f.create_dataset(
        "bomb", shape=(3,), maxshape=(None,), chunks=(rows,), dtype="<f8", compression="gzip"
    )
    bomb.id.write_direct_chunk((0,), data)
    bomb.make_scale("bomb")


@pytest.mark.parametrize(
    "edit, words",
    [
        (_huge_sweep_variable, ["dataset 'huge'", "TENSEGRITY_MAX_ARRAY_BYTES", "4294967296"]),
        (_sweep_chunk_bomb, ["dataset 'bomb'", "chunk"]),
    ],
)
def test_sweep_larger_than_the_limit_is_refused_before_reading(tmp_path, sweep_file, edit, words):
    path = crafted_sweep(tmp_path, sweep_file, edit)
    assert_one_line(run_capped("read_sweep(path)", path), path, *words)


# ---------------------------------------------------------------------- streamed files
def _partial(tmp_path: Path) -> tuple[Path, dict]:
    """An interrupted streamed run (two of five segments stored): the partial file, and the
    arguments that resume it."""
    shell = class1_shell(3, 1, damping=0.5)
    path = tmp_path / "run.h5"
    args = dict(structure=shell, t_span=(0.0, 0.5), path=path, segment=0.1, sample_dt=0.01)

    def stop(info: StreamProgress) -> None:
        if info.segment == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(**args, progress=stop)
    return Path(str(path) + PARTIAL_SUFFIX), args


def test_checkpoint_outside_the_layout_is_refused(tmp_path, secret):
    partial, _ = _partial(tmp_path)
    with h5py.File(partial, "a") as f:
        current = "ab"[int(f["checkpoint"].attrs["current"])]
        slot = f["checkpoint"][current]
        n = slot["q"].shape
        del slot["q"]
        slot.create_dataset("q", shape=n, dtype="<f8", external=[(str(secret[0]), 0, 8 * n[0])])
    assert_refused(read_checkpoint, partial, f"'checkpoint/{current}/q'", "external storage")
    with h5py.File(partial, "a") as f:
        f["checkpoint"].attrs["current"] = np.array([0, 1])
    assert_refused(read_checkpoint, partial, "'current'")


def test_a_torn_copy_of_a_checkpoint_is_refused_in_one_line(tmp_path):
    """A partial file copied while the run wrote its checkpoint: the superblock from before the
    write, the engine state's group grown past the end it records.  h5py raised a bare
    ``RuntimeError`` ("Link iteration failed (addr overflow ...)") listing the group (seen in
    CI, where ``tests/test_cli_resume.py`` reads such copies); now one line naming the file."""
    partial, _ = _partial(tmp_path)
    before = partial.read_bytes()
    with h5py.File(partial, "a") as f:
        current = "ab"[int(f["checkpoint"].attrs["current"])]
        loop = f["checkpoint"][current]["loop"]
        for i in range(40):  # past the compact link storage: a new heap at the end of the file
            loop[f"extra{i}"] = np.zeros(3)
    partial.write_bytes(before[:48] + partial.read_bytes()[48:])
    assert_refused(read_checkpoint, partial, f"group 'checkpoint/{current}/loop'", "damaged")


def test_resume_does_not_write_into_a_file_a_dataset_points_at(tmp_path, secret):
    """A partial file whose ``t`` is stored in another file: resuming refuses it, and the other
    file is unchanged (the run would append its samples there)."""
    partial, args = _partial(tmp_path)
    before = secret[0].read_bytes()
    with h5py.File(partial, "a") as f:
        rows = f["t"].shape[0]
        replace(
            f,
            "t",
            shape=(rows,),
            maxshape=(None,),
            dtype="<f8",
            external=[(str(secret[0]), 0, h5py.h5f.UNLIMITED)],
        )
    with pytest.raises(ValueError) as info:
        simulate_to_file(**args)
    assert_one_line(str(info.value), partial, "dataset 't'", "external storage")
    assert secret[0].read_bytes() == before


# ------------------------------------------------------------------ limits, under a memory cap
def _huge_time(path: Path, rows: int) -> Path:
    """A trajectory-looking file whose ``time`` claims ``rows`` samples (no data stored: HDF5
    reads the fill value)."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tensegrity-trajectory"
        f.attrs["version"] = 1
        f.create_dataset("time", shape=(rows,), dtype="<f8", chunks=(2**16,))
    return path


@pytest.mark.parametrize("size", [7 * GiB, 21 * 2**40], ids=["7GiB", "21TiB"])
def test_dataset_larger_than_the_limit_is_refused_before_reading(tmp_path, size):
    path = _huge_time(tmp_path / "huge.h5", size // 8)
    message = run_capped("read_dataset(path, 't')", path)
    assert_one_line(message, path, "dataset 'time'", "TENSEGRITY_MAX_ARRAY_BYTES", "4294967296")


def test_trajectory_larger_than_the_limit_is_refused_before_reading(tmp_path, result):
    """Every dataset of a consistent shape, 2**25 samples (17 GiB in all, 256 MiB of it
    ``time``): the sum over the datasets counts."""
    rows = 2**25

    def grow(f):
        for name in list(f):
            shape, dtype = (rows, *f[name].shape[1:]), f[name].dtype
            attrs = dict(f[name].attrs)
            replace(f, name, shape=shape, dtype=dtype, chunks=(1024, *shape[1:]))
            f[name].attrs.update(attrs)

    path = crafted(tmp_path, result, grow)
    message = run_capped("read_trajectory(path)", path)
    assert_one_line(message, path, "TENSEGRITY_MAX_ARRAY_BYTES")


def test_a_huge_chunk_is_refused(tmp_path):
    """Three samples in one chunk of 2 GiB (9 MiB on disk, compressed): reading one sample
    would decompress the whole chunk."""
    path = tmp_path / "chunk.h5"
    rows = 2**28
    deflate = zlib.compressobj(1)
    block = bytes(2**20)
    data = b"".join(deflate.compress(block) for _ in range(8 * rows // len(block)))
    data += deflate.flush()
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tensegrity-trajectory"
        f.attrs["version"] = 1
        time = f.create_dataset(
            "time", shape=(3,), maxshape=(None,), chunks=(rows,), dtype="<f8", compression="gzip"
        )
        time.id.write_direct_chunk((0,), data)
    message = run_capped("read_dataset(path, 't', every=2)", path)
    assert_one_line(message, path, "dataset 'time'", "chunk")


def _npz_with_header(path: Path, arrays: dict[str, tuple[tuple[int, ...], bytes]]) -> Path:
    """An ``.npz`` whose members have the given header shapes (float64) and raw data."""
    with zipfile.ZipFile(path, "w") as archive:
        for name, (shape, data) in arrays.items():
            header = {"descr": "<f8", "fortran_order": False, "shape": shape}
            with archive.open(f"{name}.npy", "w") as member:
                np.lib.format.write_array_header_1_0(member, header)
                member.write(data)
    return path


@pytest.mark.parametrize("size", [7 * GiB, 21 * 2**40], ids=["7GiB", "21TiB"])
def test_npz_header_asking_for_more_than_its_data_is_refused(tmp_path, size):
    path = _npz_with_header(
        tmp_path / "table.npz",
        {"time": ((size // 8,), bytes(16)), "force": ((2, 1, 3), bytes(48))},
    )
    message = run_capped("read_force_table(path)", path)
    assert_one_line(message, path, "'time'")


def test_connectivity_npz_header_asking_for_terabytes_is_refused(tmp_path):
    path = _npz_with_header(tmp_path / "net.npz", {"N": ((2**40, 3), bytes(72))})
    message = run_capped("read_network(path)", path)
    assert_one_line(message, path, "'N'")


def test_npz_array_larger_than_the_limit_is_refused(tmp_path):
    """256 MiB of real (compressed) zeros against a limit lowered to 16 MiB: the limit and the
    variable that raises it are named."""
    T, N = 2**10, 2**13
    path = tmp_path / "table.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        with archive.open("time.npy", "w") as member:
            np.lib.format.write_array(member, np.arange(T, dtype=float))
        with archive.open("force.npy", "w", force_zip64=True) as member:
            header = {"descr": "<f8", "fortran_order": False, "shape": (T, N, 3)}
            np.lib.format.write_array_header_1_0(member, header)
            block = bytes(2**20)
            for _ in range(T * N * 3 * 8 // len(block)):
                member.write(block)
    message = run_capped("read_force_table(path)", path, TENSEGRITY_MAX_ARRAY_BYTES=str(16 * 2**20))
    assert_one_line(message, path, "'force'", "TENSEGRITY_MAX_ARRAY_BYTES", "16777216")


@pytest.mark.parametrize(
    "suffix, call",
    [
        (".json", "read_structure(path)"),
        (".csv", "read_force_table(path)"),
    ],
)
def test_input_file_larger_than_the_limit_is_refused_before_reading(tmp_path, suffix, call):
    """A 2 GiB file (sparse: it takes no disk space) read whole would not fit the cap."""
    path = tmp_path / f"big{suffix}"
    with open(path, "wb") as f:
        f.truncate(2 * GiB)
    message = run_capped(call, path)
    assert_one_line(message, path, "TENSEGRITY_MAX_INPUT_BYTES", "1073741824")


def test_input_limit_can_be_lowered(tmp_path):
    path = tmp_path / "net.yaml"
    write_network(path, class1_shell(3, 1))
    limit = path.stat().st_size - 1
    message = run_capped("read_network(path)", path, TENSEGRITY_MAX_INPUT_BYTES=str(limit))
    assert_one_line(message, path, "TENSEGRITY_MAX_INPUT_BYTES", str(limit))


READERS = [
    (".json", "read_structure(path)"),
    (".yaml", "read_network(path)"),
    (".csv", "read_force_table(path)"),
    (".npz", "read_force_table(path)"),
    (".h5", "read_trajectory(path)"),
    (".h5", "read_checkpoint(path)"),
    (".yaml", "SweepSpec.from_file(path)"),
    (".nc", "read_sweep(path)"),
]


@pytest.mark.parametrize("suffix, call", READERS)
def test_fifo_is_refused_not_read_forever(tmp_path, suffix, call):
    path = tmp_path / f"input{suffix}"
    os.mkfifo(path)
    assert_one_line(run_capped(call, path), path, "not a regular file")


@pytest.mark.parametrize("suffix, call", READERS)
def test_device_is_refused_not_read_forever(tmp_path, suffix, call):
    path = tmp_path / f"input{suffix}"
    path.symlink_to("/dev/zero")
    assert_one_line(run_capped(call, path), path, "not a regular file")


def test_limit_variables_must_be_byte_counts(tmp_path, result, monkeypatch):
    path = write_trajectory(tmp_path / "run.h5", result)
    monkeypatch.setenv("TENSEGRITY_MAX_ARRAY_BYTES", "lots")
    with pytest.raises(
        ValueError, match=r"^TENSEGRITY_MAX_ARRAY_BYTES: expected a number of bytes"
    ):
        read_trajectory(path)


def test_array_limit_counts_the_bytes_read(tmp_path, result, monkeypatch):
    """A trajectory reads with the limit set to exactly the bytes of its arrays, and is refused
    one byte below; ``every`` counts only the rows it reads."""
    path = write_trajectory(tmp_path / "run.h5", result)
    arrays = (result.t, result.node_position, result.node_velocity, result.tendon_length)
    arrays += (result.tendon_tension, result.q, result.qdot, result.residual_acceleration)
    size = sum(a.nbytes for a in arrays) + 8 * result.t.size * len(result.energy)
    monkeypatch.setenv("TENSEGRITY_MAX_ARRAY_BYTES", str(size))
    assert np.array_equal(read_trajectory(path).node_position, result.node_position)
    monkeypatch.setenv("TENSEGRITY_MAX_ARRAY_BYTES", str(size - 1))
    assert_refused(read_trajectory, path, "TENSEGRITY_MAX_ARRAY_BYTES", str(size - 1))
    assert read_trajectory(path, every=2).t.size == 2  # 2 of 3 rows fit
