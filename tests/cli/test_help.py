"""``--help`` of the commands taking method knobs (transfer, run, visibility) lists every knob of the chosen
method with its default, range and meaning, and without ``--method`` each method's knobs with their
defaults; a flag the method does not know is an error naming the method and listing its knobs.

The expected defaults are read from the constructors' signatures (where ``KNOBS`` takes them from) and
formatted here; a few are also written out by hand."""

from __future__ import annotations

import inspect
import re

import pytest

from warpshade.cli import _parse, build_parser, main
from warpshade.cli.cmd_transfer import parse_knobs
from warpshade.visibility import METHODS, get_method
from warpshade.visibility.gears import AREA_METHODS, get_area_method

COMMANDS = [("transfer", name, get_method) for name in sorted(METHODS)] \
    + [("run", name, get_method) for name in sorted(METHODS)] \
    + [("visibility", name, get_area_method) for name in AREA_METHODS]


def help_text(capsys, argv) -> str:
    """The ``--help`` output of ``argv``, whitespace collapsed (argparse wraps to the terminal's width)."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 0
    return " ".join(capsys.readouterr().out.split())


def shown(value) -> str:
    """A default as the help writes it."""
    if value is None:
        return "none"
    if isinstance(value, tuple):
        return ",".join(str(int(x)) if float(x) == int(x) else str(x) for x in value)
    return str(value)


def cli_knobs(cls):
    """(knob, constructor default) of every command-line knob."""
    params = inspect.signature(cls.__init__).parameters
    return [(k, params[k.name].default) for k in cls.SCHEMA if k.cli]


def entry(k) -> str:
    """How a knob's entry starts in the full listing: its flag and metavar (a switch: the flag alone)."""
    if k.type is bool:
        return ("--no-" if k.default else "--") + k.name.replace("_", "-") + " "
    metavar = "{" + ",".join(str(c) for c in k.choices) + "}" if k.choices else k.name.upper()
    return f"--{k.name.replace('_', '-')} {metavar} "


@pytest.mark.parametrize("command, name, lookup", COMMANDS)
def test_help_with_a_method_lists_each_knob_with_its_default(capsys, command, name, lookup):
    cls = lookup(name)
    text = help_text(capsys, [command, "--method", name, "--help"])
    section = text.split(f"knobs of --method {name}:", 1)[1]
    starts = []
    for k, default in cli_knobs(cls):
        at = section.find(entry(k), starts[-1] if starts else 0)
        assert at >= 0, (k.name, section)
        starts.append(at)
    for (k, default), a, b in zip(cli_knobs(cls), starts, starts[1:] + [len(section)]):
        text_k = section[a:b]
        assert k.help in text_k, k.name  # the meaning, from KNOBS
        if k.type is bool:
            assert f"(default: {k.name} {'on' if default else 'off'})" in text_k, text_k
        else:
            assert f"(default {shown(default)})" in text_k, text_k


@pytest.mark.parametrize("argv", [["transfer", "--help", "--method", "hemiraster"],
                                  ["transfer", "--method=hemiraster", "-h"]])
def test_help_finds_the_method_wherever_it_is(capsys, argv):
    assert "--mask {8,16,32,64} visibility mask pixels across (default 32)" in help_text(capsys, argv)


def test_help_lines_written_out(capsys):
    """Hand-written expectations: defaults, ranges and choices of a few knobs."""
    hemi = help_text(capsys, ["transfer", "--method", "hemiraster", "--help"])
    assert "--mask {8,16,32,64} visibility mask pixels across (default 32)" in hemi
    assert "--lut LUT plane LUT cube-map resolution R (6*R*R planes); an integer >= 1 (default 48)" in hemi
    assert "--no-cull disable cluster culling (default: cull on)" in hemi
    assert "--view VIEW glossy: direction towards the viewer x,y,z (world) (default 0,0,1)" in hemi
    assert "--rays" not in hemi  # only the chosen method's knobs
    ref = help_text(capsys, ["transfer", "--method", "reference", "--help"])
    assert "--rays RAYS rays per vertex (rounded to a square); an integer >= 1 (default 1024)" in ref
    disks = help_text(capsys, ["run", "--method", "disks", "--help"])
    assert "; a number in 0..1 or unset (default none)" in disks
    assert "--sides {auto,one,two}" in disks and "(default auto)" in disks
    gears = help_text(capsys, ["visibility", "--method", "gears", "--help"])
    assert "--k K k×k light samples per vertex; an integer in 1..32 (default 16)" in gears
    assert "an integer in 0..1024 (default 16)" in gears  # --grid
    area_ref = help_text(capsys, ["visibility", "--method", "reference", "--help"])
    assert "--no-jitter rays through light cell centres (default: jitter on)" in area_ref


@pytest.mark.parametrize("command, methods, lookup", [("transfer", sorted(METHODS), get_method),
                                                      ("run", sorted(METHODS), get_method),
                                                      ("visibility", list(AREA_METHODS), get_area_method)])
def test_help_without_a_method_summarises_every_methods_knobs(capsys, command, methods, lookup):
    text = help_text(capsys, [command, "--help"])
    summary = text.split("Defaults:", 1)[1]
    for name in methods:
        line = summary.split(f" {name}: ", 1)[1]
        line = re.split(r" [a-z]+: --", line, maxsplit=1)[0]  # up to the next method
        for k, default in cli_knobs(lookup(name)):
            if k.type is bool:
                flag = ("--no-" if default else "--") + k.name.replace("_", "-")
                assert f"{flag} ({k.name} {'on' if default else 'off'})" in line, (name, k.name, line)
            else:
                assert f"--{k.name.replace('_', '-')} {shown(default)}" in line, (name, k.name, line)


def test_help_summary_written_out(capsys):
    text = help_text(capsys, ["transfer", "--help"])
    assert "warpshade transfer --method NAME --help" in text
    assert "reference: --rays 1024, --seed 0, --offset 1e-05" in text
    assert "hemiraster: --mask 32, --lut 48," in text
    assert "spheres: --spheres 30," in text
    assert "gears: --k 16, --offset 1e-05, --grid 16" in help_text(capsys, ["visibility", "--help"])


@pytest.mark.parametrize("command, name, lookup", [c for c in COMMANDS if c[0] != "visibility"])
def test_help_defaults_are_what_the_command_uses(capsys, command, name, lookup):
    """The default a help line shows is the value the command hands the method when the flag is not given."""
    argv = [command, "--method", name] + (["m.obj", "--save", "o.npz"] if command == "transfer" else [])
    knobs = parse_knobs(_parse(build_parser(), argv))
    text = help_text(capsys, argv + ["--help"])
    for k, _ in cli_knobs(lookup(name)):
        value = knobs[k.name]
        want = f"(default: {k.name} {'on' if value else 'off'})" if k.type is bool else f"(default {shown(value)})"
        assert want in text, (k.name, value)


def error_line(capsys, argv) -> str:
    assert main(argv) == 1
    return capsys.readouterr().err.strip().splitlines()[-1]


def test_unknown_knob_names_the_method_and_lists_its_knobs(tmp_path, capsys):
    save = str(tmp_path / "o.npz")
    assert error_line(capsys, ["transfer", str(tmp_path / "m.obj"), "--method", "reference", "--save", save,
                               "--rayz", "3"]) == (
        "warpshade transfer: error: unknown option(s) for method 'reference': --rayz 3 (its knobs: --rays, --seed, "
        "--offset; warpshade transfer --method reference --help describes them)")
    line = error_line(capsys, ["transfer", str(tmp_path / "m.obj"), "--method", "hemiraster", "--save", save,
                               "--bogus", "3"])
    assert line.startswith("warpshade transfer: error: unknown option(s) for method 'hemiraster': --bogus 3 "
                           "(its knobs: --mask, --lut, --downsample, --ring, ")
    assert all(f" {k.cli_flag}," in line or f" {k.cli_flag};" in line for k in get_method("hemiraster").SCHEMA
               if k.cli)
    assert "--rim" not in line and "--no-rim" not in line  # not a command-line knob
    assert error_line(capsys, ["visibility", str(tmp_path / "m.obj"), "--rect-light", "0,0,1,1,0,0,0,1,0",
                               "--method", "gears", "--save", save, "--jitter", "1"]) == (
        "warpshade visibility: error: unknown option(s) for method 'gears': --jitter 1 (its knobs: --k, --offset, "
        "--grid; warpshade visibility --method gears --help describes them)")
    assert not (tmp_path / "o.npz").exists()


def test_unknown_knob_in_run(tmp_path, capsys):
    out = str(tmp_path / "o.usda")
    assert error_line(capsys, ["run", "--method", "disks", "--bogus", "--out", out]) == (
        "warpshade run: error: unknown option(s) for method 'disks': --bogus (its knobs: --lod, --passes, --sides, "
        "--samples, --back-weight; warpshade run --method disks --help describes them)")
    assert error_line(capsys, ["run", "--method", "none", "--rays=4", "--out", out]) == (
        "warpshade run: error: unknown option(s) for method 'none': --rays=4 (it has no knobs)")
    assert error_line(capsys, ["run", "--rays=4", "--out", out]) == (
        "warpshade run: error: unknown option(s) --rays=4 (not an option of warpshade run, and method knobs need "
        "--method; warpshade run --help lists its options and each method's knobs)")
    assert error_line(capsys, ["run", "--output", out]) == (
        "warpshade run: error: unknown option(s) --output (not an option of warpshade run, and method knobs need "
        "--method; warpshade run --help lists its options and each method's knobs)")
    assert not (tmp_path / "o.usda").exists()


def test_run_output_short_flag():
    # -o names the output, as in warpshade preview and export
    from warpshade.cli import _parse, build_parser

    assert _parse(build_parser(), ["run", "-o", "mine.usda"]).out == "mine.usda"
    assert _parse(build_parser(), ["run", "--out", "mine.usda"]).out == "mine.usda"
