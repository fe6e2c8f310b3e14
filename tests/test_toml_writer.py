"""The TOML form is written by ``tomli-w`` (issue 16): whatever a structure's names hold, the file
reads back (the hand-written writer escaped non-BMP characters as JSON surrogate pairs, which no
TOML reader takes)."""

from __future__ import annotations

import tomllib

from tensegrity import class1_shell
from tensegrity.io.formats import network_to_dict, read_network, write_network

#: Tendon names no bare TOML key or plain string holds: characters outside the Basic
#: Multilingual Plane, quotes, backslashes, control characters, other scripts.
NAMES = ("ten😀don", "\U0001d531 2", 'q"uote', "back\\slash", "tab\there", "del\x7f", "é", "日本")


def test_names_outside_the_basic_multilingual_plane_round_trip_through_toml(tmp_path):
    shell = class1_shell(3, 1)
    structure = shell.replace(tendon_name=NAMES + shell.tendon_name[len(NAMES) :])
    path = write_network(tmp_path / "s.toml", structure)
    back = read_network(path)
    assert back.tendon_name == structure.tendon_name
    assert back.to_dict() == structure.to_dict()
    text = path.read_text(encoding="utf-8")
    assert tomllib.loads(text) == network_to_dict(structure)
    assert "ten😀don" in text  # written as the character, not as an escape
