"""What ``--help`` and ``--version`` say, and the command's first errors (a new-user
walkthrough): every verb's description is its whole paragraph in plain text (not a docstring's
first line cut mid-sentence, with reST's double backticks), every option with a default shows
it, ``--version`` prints the installed version, and no verb or a ``matrices`` of a structure the
matrix model does not take are one line naming what to give."""

from __future__ import annotations

import argparse
import importlib.metadata

import pytest

from tensegrity.cli import arguments, inspection
from tensegrity.cli.main import build_parser, main


def _verb_parsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


VERBS = list(_verb_parsers())


def _help(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """What ``tensegrity ARGV --help`` prints (it exits 0)."""
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


def _flat(text: str) -> str:
    """``text`` without its whitespace: the help wraps lines (and may break at a hyphen)."""
    return "".join(text.split())


def test_every_verb_is_checked():
    assert len(VERBS) >= 15 and {"design", "fit", "info", "export", "matrices"} <= set(VERBS)


@pytest.mark.parametrize("verb", VERBS)
def test_each_verb_s_help_describes_it_in_whole_sentences(verb, capsys):
    """The paragraph after the usage is the verb's description: a sentence from its capital to
    its full stop, without reST markup (``design`` and ``fit`` showed their docstrings' first
    line: "``tensegrity design``: minimal-mass members ..., at")."""
    printed = _help([verb], capsys)
    description = _verb_parsers()[verb].description
    assert description, f"{verb} has no description"
    paragraph = printed.split("\n\n")[1]  # after the usage
    assert not paragraph.startswith(("options:", "positional arguments:")), printed
    assert _flat(paragraph) == _flat(description)
    text = " ".join(paragraph.split())
    assert text[0].isupper() and text.endswith("."), text
    assert "``" not in text and ":func:" not in text and ":mod:" not in text, text
    assert not text.startswith("tensegrity "), text  # the usage line names the verb
    assert len(text) > 80, text


@pytest.mark.parametrize(
    "verb, whole",
    [
        (
            "design",
            "Minimal-mass members for a structure's geometry under load cases, at the given "
            "geometry or at each case's loaded equilibrium (tensegrity.design.loaded.size, "
            "docs/design.md); writes the sized structure and a report to --out.",
        ),
        (
            "fit",
            "A structure's parameters fitted to measured motion: marker positions, tendon "
            "lengths, tensions (tensegrity.analysis.identification.fit, "
            "docs/identification.md); writes the fitted structure, the estimates and a figure to "
            "--out.",
        ),
    ],
)
def test_design_and_fit_describe_themselves_by_their_docstring_s_whole_paragraph(
    verb, whole, capsys
):
    assert _flat(whole) in _flat(_help([verb], capsys))


def test_a_description_is_a_docstring_s_first_paragraph_in_plain_text():
    doc = """``tensegrity thing``: one :func:`tensegrity.a.b` and
    :class:`~tensegrity.c.D`, ``code`` too::

        tensegrity thing --x 1

    More.
    """
    assert arguments.description(doc) == "One tensegrity.a.b and D, code too."
    assert arguments.description(None) is None


def _option_help(verb: str, option: str, capsys: pytest.CaptureFixture[str]) -> str:
    """The help of ``verb``'s ``option`` as printed, on one line."""
    lines = _help([verb], capsys).splitlines()
    start = next(
        i for i, line in enumerate(lines) if line.strip().split(" ")[0].rstrip(",") == option
    )
    entry = [lines[start]]
    for line in lines[start + 1 :]:
        if not line.startswith(" " * 6):  # the next option, or a group's title
            break
        entry.append(line)
    return " ".join(" ".join(entry).split())


def _default(verb: str, dest: str) -> object:
    """The value of ``verb``'s option ``dest`` when it is not given."""
    return vars(build_parser().parse_args([verb]))[dest]


@pytest.mark.parametrize(
    "verb, option, dest, unit",
    [
        ("equilibrium", "--t-end", "t_end", "[s]"),
        ("matrices", "--t-end", "t_end", "[s]"),
        ("control", "--move-time", "move_time", "[s]"),
        ("control", "--settle-time", "settle_time", "[s]"),
    ],
)
def test_the_times_show_their_default_and_unit(verb, option, dest, unit, capsys):
    """Their default, read from the parser (one source): it was missing from ``--help``."""
    default = _default(verb, dest)
    assert isinstance(default, float)
    text = _option_help(verb, option, capsys)
    assert f"{unit} (default {default:g})" in text, text


def test_matrices_at_shows_its_default(capsys):
    assert _default("matrices", "at") == "initial"
    assert "(default initial)" in _option_help("matrices", "--at", capsys)


def test_animate_duration_says_what_it_is_unless_given(capsys):
    from tensegrity.plots.motion import MAX_REAL_TIME

    text = _option_help("animate", "--duration", capsys)
    assert (
        f"length of the video [s] (default: as long as the run, at most {MAX_REAL_TIME:g} s;"
        in (text)
    )
    assert "with --speed" in text


def test_sweep_param_says_what_a_parameter_not_varied_takes_and_load_s_unit(capsys):
    from tensegrity.sweep.run import DEFAULTS

    text = _option_help("sweep", "--param", capsys)
    assert "load [N]" in text and "stiffness [N/m]" in text and "damping [N s/m]" in text, text
    not_varied = ", ".join(f"{name} = {value:g}" for name, value in DEFAULTS.items())
    assert f"A parameter not varied is {not_varied} (with --structure: the file's values" in text


@pytest.mark.parametrize("verb", VERBS)
def test_every_option_with_a_default_value_shows_it(verb):
    """An option whose value is not None when it is not given says its default in its help
    (docs/cli.md: ``--help`` lists every option with its default)."""
    silent = [
        action.option_strings[-1]
        for action in _verb_parsers()[verb]._actions
        if action.option_strings
        and action.nargs != 0  # a flag
        and not action.required
        and action.default not in (None, [], argparse.SUPPRESS)
        and "default" not in (action.help or "")
    ]
    assert not silent, f"{verb}: no default in the help of {silent}"


def test_version_prints_the_installed_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    printed = capsys.readouterr()
    assert printed.out == f"tensegrity {importlib.metadata.version('tensegrity-dynamics')}\n"
    assert printed.err == ""


@pytest.mark.parametrize("argv", [[], ["--debug"]])
def test_no_verb_is_one_line_naming_the_verbs(argv, capsys):
    """Not argparse's "the following arguments are required: command"."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("tensegrity: error: a verb is required (simulate, info, "), err
    assert ", ".join(VERBS) in err and err.endswith(": see tensegrity --help\n"), err


def test_an_unknown_option_without_a_verb_is_one_line(capsys):
    assert main(["--bogus"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("tensegrity: error: unrecognized arguments: --bogus; a verb is required")


def _no_work(*_args, **_kwargs):
    raise AssertionError("the structure was built: the options were not checked first")


@pytest.mark.parametrize(
    "argv, given",
    [
        (["--kind", "prism"], "--kind prism"),
        (["--kind", "tower", "--at", "equilibrium"], "--kind tower"),
        (["--fixed-base"], "--fixed-base"),
    ],
)
def test_matrices_of_another_kind_is_refused_first_naming_the_option(
    argv, given, capsys, tmp_path, monkeypatch
):
    """It said "tendons: 'b0' is not a shell tendon name t<alpha>_<i>_<j>; ...", naming no
    option the user gave, after building the structure."""
    monkeypatch.setattr(inspection, "structure_of", _no_work)
    monkeypatch.chdir(tmp_path)
    assert main(["matrices", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"tensegrity: error: {given}: the matrix model: supports only"), err
    assert "class 1 shells (--kind shell" in err, err
    assert not list(tmp_path.iterdir())


def test_matrices_of_a_structure_file_not_a_shell_is_refused_before_the_simulation(
    capsys, tmp_path, monkeypatch
):
    import tensegrity.engine.simulate

    path = tmp_path / "prism.json"
    assert main(["export", "--kind", "prism", "-o", str(path)]) == 0
    capsys.readouterr()
    monkeypatch.setattr(tensegrity.engine.simulate, "simulate", _no_work)
    out = tmp_path / "m"
    argv = ["matrices", "--structure", str(path), "--at", "equilibrium", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("tensegrity: error: --structure: ") and "prism.json" in err, err
    assert "the matrix model needs a class 1 shell" in err, err
    assert not out.exists()


@pytest.mark.parametrize("argv", [["design"], ["--debug", "fit"], ["sweep"]])
def test_a_verb_whose_options_are_built_on_demand_shows_them(argv, capsys):
    """``sweep``, ``design`` and ``fit`` are only named until the command line asks for one
    (their options import SciPy): then its help lists its options."""
    printed = _help(argv, capsys)
    assert "options:" in printed and "--out" in printed and "--structure" in printed, printed
