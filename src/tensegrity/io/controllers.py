"""Controller files: a :class:`~tensegrity.engine.feedback.LinearFeedback` as ``.npz``.

The arrays (the law ``u = u_ref - K (y - y_ref)``, :mod:`tensegrity.engine.feedback`):

- ``K`` (A, Y) float: the gain;
- ``y_ref`` (Y,) float: the outputs' reference;
- ``u_ref`` (A,) float: the controls at the reference [m];
- ``period`` () float: the time between updates [s];
- ``outputs`` (G,) text: the output groups ``y`` stacks (``"position"``, ``"velocity"``,
  ``"length"``, ``"tension"``, in that order);
- ``tendons`` (A,) text: the actuated tendons' names.

Written by ``tensegrity lqr`` and read by ``tensegrity simulate --controller``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tensegrity.engine.feedback import LinearFeedback
from tensegrity.io.checked import ArrayKind, npz_arrays, open_npz
from tensegrity.io.files import PathLike, atomic_path, file_error, read_input
from tensegrity.model.structure import Structure

__all__ = ["read_controller", "write_controller"]

_NUMBERS = ArrayKind("iuf", "real numbers")
_TEXT = ArrayKind("U", "text")
#: The arrays of a controller file and what each may hold.
FIELDS = {
    "K": _NUMBERS,
    "y_ref": _NUMBERS,
    "u_ref": _NUMBERS,
    "period": _NUMBERS,
    "outputs": _TEXT,
    "tendons": _TEXT,
}


def write_controller(path: PathLike, feedback: LinearFeedback, structure: Structure) -> Path:
    """Write ``feedback`` to the ``.npz`` controller file ``path``, atomically.

    The law is first checked against ``structure`` (:meth:`LinearFeedback.check`: its outputs'
    size and tendons); the file names the tendons (``structure.tendon_name``), whatever form
    ``feedback.tendons`` has.  ``ValueError`` naming the field that does not fit.
    """
    index = feedback.check(structure)
    names = np.array([structure.tendon_name[i] for i in index], dtype=str)
    with atomic_path(path) as tmp, open(tmp, "wb") as stream:
        np.savez(
            stream,
            K=feedback.K,
            y_ref=feedback.y_ref,
            u_ref=feedback.u_ref,
            period=np.float64(feedback.period),
            outputs=np.array(feedback.outputs, dtype=str),
            tendons=names,
        )
    return Path(path)


def read_controller(path: PathLike) -> LinearFeedback:
    """The :class:`LinearFeedback` of the controller file ``path`` (module docstring).

    The file is read whole within ``TENSEGRITY_MAX_INPUT_BYTES``, each array only after its
    header is checked (:func:`tensegrity.io.checked.npz_arrays`).

    Raises
    ------
    ValueError
        One line starting with the file name and naming the field at fault, e.g.
        ``"gains.npz: missing array 'period' (expected K, y_ref, u_ref, period, outputs,
        tendons)"``, ``"gains.npz: K: expected shape (len(u_ref), len(y_ref)) = (3, 12), got
        (3, 10)"``.
    """
    raw = read_input(path)
    try:
        with open_npz(raw) as archive:
            missing = [name for name in FIELDS if name not in archive.files]
            if missing:
                raise ValueError(f"missing array {missing[0]!r} (expected {', '.join(FIELDS)})")
            arrays = npz_arrays(archive, FIELDS, kinds=FIELDS)
        period = arrays["period"]
        if period.shape != ():
            raise ValueError(f"period: expected one number [s], got shape {period.shape}")
        for name in ("outputs", "tendons"):
            if arrays[name].ndim != 1:
                raise ValueError(
                    f"{name}: expected a list of names, got shape {arrays[name].shape}"
                )
        return LinearFeedback(
            arrays["K"],
            arrays["y_ref"],
            arrays["u_ref"],
            float(period),
            tuple(str(g) for g in arrays["outputs"]),
            tuple(str(t) for t in arrays["tendons"]),
        )
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc
