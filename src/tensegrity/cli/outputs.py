"""Where the verbs' outputs go, one rule for all (docs/reliability.md, "Outputs all together, or
not at all"): a verb makes the missing folders of its outputs, a folder (``--out``, ``vtk
--output``) or a file (``sweep``, ``export``, ``animate``, ``view --output FILE``), and removes
them again if it writes nothing there (:func:`tensegrity.io.files.folders_made`).  What cannot
become a folder or a file is refused up front, before any work, in one line naming the option.
"""

from __future__ import annotations

from pathlib import Path

from tensegrity.cli.errors import CommandError
from tensegrity.io.files import shown_path

__all__ = ["check_file", "check_folder"]


def check_folder(folder: Path, option: str) -> None:
    """Fail up front, before any work, if ``folder`` cannot be (or become) a folder: a file
    stands there or where one of its missing parents goes."""
    for path in (folder, *folder.parents):
        if path.exists():
            if not path.is_dir():
                raise CommandError(f"{option}: {shown_path(path)} exists and is not a folder")
            return


def check_file(path: Path, option: str) -> None:
    """Fail up front, before any work, if the file ``path`` cannot be written: a folder stands
    there, or its folder cannot become one (:func:`check_folder`)."""
    if path.is_dir():
        raise CommandError(f"{option}: {shown_path(path)} is a folder, expected a file name")
    check_folder(path.parent, option)
