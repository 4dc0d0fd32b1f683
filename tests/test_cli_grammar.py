"""One grammar for every command line (gsverse_format/cli/grammar.py, README "Command-line
grammar"): the same flag means the same thing in every tool, bad usage is one line and exit 2,
a missing or unreadable input one line naming it and exit 1, existing outputs are refused
without -w, and -o is the positional OUTPUT.

Inputs are built here from the shipped example's splats and mesh (the anchored GLB too)."""
from __future__ import annotations

import contextlib
import io
import json
import os
import pathlib

import pytest

import gsverse_format as gv
from gsverse_format.cli import convert, info, pose, render
from gsverse_format.cli.grammar import HELP_JSON, HELP_OUTPUT, HELP_OVERWRITE, HELP_QUIET
from gsverse_format.conformance import cli as conformance
from gsverse_format.validators import cli as validate
from gsverse_format.version import __version__

REPO = pathlib.Path(__file__).resolve().parents[1]
CAPSULE = REPO / "examples" / "capsule"

TOOLS = {"gsverse-convert": convert, "gsverse-validate": validate, "gsverse-pose": pose,
         "gsverse-render": render, "gsverse-info": info, "gsverse-conformance": conformance}
#: The tools that write files: -w and -o.
WRITERS = ("gsverse-convert", "gsverse-render", "gsverse-pose")


def run(tool: str, *args) -> tuple[int, str, str]:
    """``tool``'s ``main`` in this process: (exit status, stdout, stderr); argparse's exits
    (usage errors, --help, --version) count as the status they carry."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = TOOLS[tool].main([str(a) for a in args])
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 2)
    return code, out.getvalue(), err.getvalue()


def one_line(text: str) -> str:
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    assert "Traceback" not in text
    return lines[0]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> pathlib.Path:
    """anchored.glb (the example anchored to its mesh), garbage inputs, and nothing else."""
    folder = tmp_path_factory.mktemp("grammar")
    gv.convert(CAPSULE / "splats.ply", folder / "anchored.glb", mesh=str(CAPSULE / "mesh.obj"))
    (folder / "garbage.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement ver")
    (folder / "garbage.glb").write_bytes(b"glTF\x02\x00\x00\x00garbage")
    return folder


def good_args(tool: str, data: pathlib.Path, out: pathlib.Path) -> list:
    """A valid command line of ``tool`` writing (if it writes) to ``out`` (a suffix-less name:
    each tool's own suffix is added)."""
    return {"gsverse-convert": [CAPSULE / "splats.ply", out.with_suffix(".glb"), "--plain"],
            "gsverse-validate": [data / "anchored.glb"],
            "gsverse-pose": [data / "anchored.glb", out.with_suffix(".ply"), "--deform",
                             "twist=30"],
            "gsverse-render": [data / "anchored.glb", out.with_suffix(".png"), "--size",
                               "16x16"],
            "gsverse-info": [data / "anchored.glb"],
            "gsverse-conformance": ["check", data / "no-suite", data / "no-results"]}[tool]


# ---------------------------------------------------------------------------- the flags

def _parsers(tool: str) -> list:
    parser = TOOLS[tool].build_parser()
    subs = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    return [parser] + [p for a in subs for p in a.choices.values()]


def _action(parser, flag: str):
    return next((a for a in parser._actions if flag in a.option_strings), None)


@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_the_same_flag_means_the_same_thing(tool):
    parsers = _parsers(tool)
    commands = parsers[1:] or parsers       # conformance: the flags are its subcommands'
    for parser in commands:
        for flags, dest, help_text in ((("--json",), "json", HELP_JSON),
                                       (("-q", "--quiet"), "quiet", HELP_QUIET)):
            action = _action(parser, flags[0])
            assert action is not None, (parser.prog, flags)
            assert tuple(action.option_strings) == flags and action.dest == dest
            assert action.nargs == 0 and action.const is True and action.default is False
            assert action.help.startswith(help_text)
    writes = tool in WRITERS
    for parser in parsers:
        for flags, dest, help_text in ((("-w", "--overwrite"), "overwrite", HELP_OVERWRITE),
                                       (("-o", "--output"), "output", HELP_OUTPUT)):
            action = _action(parser, flags[0]) or _action(parser, flags[1])
            if not writes:
                assert action is None, (parser.prog, flags)
                continue
            assert action is not None and tuple(action.option_strings) == flags
            assert action.dest == dest and action.help.startswith(help_text)
            if dest == "output":
                assert action.nargs is None and action.default is None      # one path
            else:
                assert action.nargs == 0 and action.const is True
        assert _action(parser, "-h").option_strings == ["-h", "--help"]
    version = _action(parsers[0], "--version")
    assert version.option_strings == ["--version"] and version.version == f"{tool} {__version__}"


@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_version_and_help(tool):
    code, out, err = run(tool, "--version")
    assert (code, out, err) == (0, f"{tool} {__version__}\n", "")
    code, out, err = run(tool, "--help")
    assert code == 0 and out.startswith("usage: ") and tool in out and err == ""


# ---------------------------------------------------------------------------- bad usage

@pytest.mark.parametrize("tool", sorted(TOOLS))
def test_bad_usage_is_one_line_and_exit_2(tool, data, tmp_path):
    code, out, err = run(tool, *good_args(tool, data, tmp_path / "o"), "--bogus")
    assert code == 2 and out == ""
    line = one_line(err)
    assert line.startswith(f"{tool}") and ": error: " in line and "--bogus" in line
    code, out, err = run(tool, *good_args(tool, data, tmp_path / "o"), "--bogus", "--json")
    assert code == 2 and json.loads(out)["error"]["kind"] == "usage"
    assert json.loads(out)["exit"] == 2 and "--bogus" in one_line(err)
    code, out, err = run(tool)                                    # nothing at all
    assert code == 2 and out == "" and ": error: " in one_line(err)
    assert not [p for p in tmp_path.iterdir()]


# ---------------------------------------------------------------------------- bad input

MISSING = {"gsverse-convert": lambda d, t: [t / "missing.ply", t / "o.glb"],
           "gsverse-validate": lambda d, t: [t / "missing.glb"],
           "gsverse-pose": lambda d, t: [t / "missing.glb", t / "o.ply", "--deform", "twist=9"],
           "gsverse-render": lambda d, t: [t / "missing.glb", t / "o.png"],
           "gsverse-info": lambda d, t: [t / "missing.glb"]}


@pytest.mark.parametrize("tool", sorted(MISSING))
def test_a_missing_input_is_one_line_naming_it(tool, data, tmp_path):
    args = MISSING[tool](data, tmp_path)
    code, out, err = run(tool, *args)
    line = one_line(err)
    assert line == f"{tool}: error: {args[0]}: file not found"
    # bad input, exit 1; gsverse-validate keeps its validator status 2 ("could not be
    # validated", spec/validation.md), with its report on stdout
    assert code == (2 if tool == "gsverse-validate" else 1)
    assert not [p for p in tmp_path.iterdir()]
    code, out, err = run(tool, *args, "--json")
    doc = json.loads(out)
    if tool != "gsverse-validate":
        assert doc["exit"] == 1 and doc["error"]["kind"] == "input"
        assert doc["error"]["path"] == str(args[0]) and doc["input"] == str(args[0])
    else:
        (report,) = doc["reports"]
        assert report["uri"] == str(args[0]) and report["issues"]["numErrors"] == 1


@pytest.mark.parametrize("tool, name", [("gsverse-convert", "garbage.ply"),
                                        ("gsverse-pose", "garbage.glb"),
                                        ("gsverse-render", "garbage.glb"),
                                        ("gsverse-info", "garbage.glb"),
                                        ("gsverse-info", "garbage.ply")])
def test_an_unreadable_input_is_one_line_naming_it_exit_1(tool, name, data, tmp_path):
    args = MISSING[tool](data, tmp_path)
    args[0] = data / name
    code, out, err = run(tool, *args)
    assert code == 1 and out == ""
    assert one_line(err).startswith(f"{tool}: error: {data / name}: ")
    assert not [p for p in tmp_path.iterdir()]


def test_a_missing_mesh_or_source_is_bad_input_too(data, tmp_path):
    code, _, err = run("gsverse-convert", CAPSULE / "splats.ply", tmp_path / "o.glb", "--mesh",
                       tmp_path / "none.obj")
    assert code == 1 and one_line(err).endswith(f"{tmp_path / 'none.obj'}: file not found")
    code, _, err = run("gsverse-pose", data / "anchored.glb", tmp_path / "o", "--source",
                       tmp_path / "none.npz", "--times", "0")
    assert code == 1 and str(tmp_path / "none.npz") in one_line(err)
    assert not [p for p in tmp_path.iterdir()]


# ---------------------------------------------------------------------------- outputs

@pytest.mark.parametrize("tool", WRITERS)
def test_existing_outputs_are_refused_without_w(tool, data, tmp_path):
    args = good_args(tool, data, tmp_path / "o")
    target = pathlib.Path(args[1])
    target.write_bytes(b"keep")
    for spelling in (args, [args[0], "-o", args[1], *args[2:]]):
        code, out, err = run(tool, *spelling)
        assert code == 2 and out == ""
        line = one_line(err)
        assert str(target) in line and "-w/--overwrite" in line
        assert target.read_bytes() == b"keep"
        assert sorted(p.name for p in tmp_path.iterdir()) == [target.name]   # no temporary
    code, out, err = run(tool, *args, "-w", "-q")
    assert (code, out, err) == (0, "", "")
    assert target.read_bytes() != b"keep" and target.stat().st_size > 100


@pytest.mark.parametrize("tool", WRITERS)
def test_dash_o_is_output(tool, data, tmp_path):
    """-o OUT writes what OUT writes; -o with a name that is neither an output file nor a
    folder is refused, and never becomes a folder."""
    args = good_args(tool, data, tmp_path / "a")
    assert run(tool, *args, "-q")[0] == 0
    b = pathlib.Path(args[1]).with_name("b" + pathlib.Path(args[1]).suffix)
    assert run(tool, args[0], "-o", b, *args[2:], "-q")[0] == 0
    if tool == "gsverse-convert":     # a GLB names its generator only: compare what it holds
        first, second = gv.read(args[1]), gv.read(b)
        assert first.splat_count() == second.splat_count() == 3000
        assert (first.primitives[0].splats.means == second.primitives[0].splats.means).all()
    else:
        assert pathlib.Path(args[1]).read_bytes() == b.read_bytes()
    code, out, err = run(tool, args[0], "-o", tmp_path / "c.v2", *args[2:])
    assert code == 2 and "c.v2" in one_line(err)
    code, out, err = run(tool, args[0], args[1], "-o", tmp_path / "d.glb", *args[2:])
    assert code == 2 and ": error: " in one_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([pathlib.Path(args[1]).name,
                                                                 b.name])


def test_convert_with_one_input_and_dash_o_file_writes_that_file(tmp_path):
    """The reported trap: gsverse-convert in.ply -o out.glb made a folder out.glb/."""
    code, out, err = run("gsverse-convert", CAPSULE / "splats.ply", "-o", tmp_path / "out.glb",
                         "--plain", "-q")
    assert (code, out, err) == (0, "", "")
    assert (tmp_path / "out.glb").is_file() and gv.read(tmp_path / "out.glb").splat_count()
    code, out, err = run("gsverse-convert", CAPSULE / "splats.ply", CAPSULE / "splats.ply",
                         "-o", tmp_path / "two.glb", "--plain")
    assert code == 2 and "--output-dir DIR" in one_line(err)
    assert sorted(os.listdir(tmp_path)) == ["out.glb"]


# ---------------------------------------------------------------------------- --json, -q

@pytest.mark.parametrize("tool", sorted(set(TOOLS) - {"gsverse-conformance"}))
def test_json_is_one_document_and_quiet_prints_nothing_but_the_verdict(tool, data, tmp_path):
    args = good_args(tool, data, tmp_path / "j")
    code, out, err = run(tool, *args, "--json")
    assert code == 0 and isinstance(json.loads(out), dict) and err == ""
    for p in tmp_path.iterdir():
        p.unlink()
    code, out, err = run(tool, *args, "-q")
    assert code == 0 and err == ""
    if tool in WRITERS:
        assert out == ""
    else:    # a report's verdict: one line for the one file
        assert one_line(out).startswith(f"{data / 'anchored.glb'}: ")


def test_validate_json_is_format_json(data):
    a = run("gsverse-validate", data / "anchored.glb", "--json")
    b = run("gsverse-validate", data / "anchored.glb", "--format", "json")
    first, second = json.loads(a[1]), json.loads(b[1])
    for doc in (first, second):
        doc["reports"][0].pop("seconds", None)
        doc["reports"][0]["info"].pop("seconds", None)
    assert a[0] == b[0] == 0 and first == second
    code, out, err = run("gsverse-validate", data / "anchored.glb", "--json", "--format", "text")
    assert code == 2 and json.loads(out)["error"]["kind"] == "usage" and one_line(err)


def test_conformance_json_errors_and_quiet(data, tmp_path):
    code, out, err = run("gsverse-conformance", "check", tmp_path / "suite", tmp_path / "r",
                         "--json")
    doc = json.loads(out)
    assert code == doc["exit"] and code in (1, 2) and doc["error"]["path"]
    assert one_line(err).startswith("gsverse-conformance: error: ")
    code, out, err = run("gsverse-conformance", "check", tmp_path / "suite", tmp_path / "r",
                         "--json", "--format", "text")
    assert code == 2 and json.loads(out)["error"]["kind"] == "usage"
