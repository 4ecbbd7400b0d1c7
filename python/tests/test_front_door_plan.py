"""The plan's front door from Python: every option of the library's plan (`PlanOptions`) is a
keyword of `rkwave.Plan` named as the flag of `rkwave plan`, gives the command line's
positions bit for bit, and is refused where the command line refuses it, with its words. The
binary's side: tests/front_door_plan.rs, tests/front_door_plan_share.rs."""

import inspect
import pathlib
import re
import warnings

import numpy as np
import pytest

import rkwave
from conftest import cli_error, disc_scene

W, H, SPP = 32, 32, 4
STUBS = pathlib.Path(rkwave.__file__).with_name("_rkwave.pyi")

# Flags of `rkwave plan` that are the command line's way of driving the plan through files
# (and its global ones), each with what stands for it in Python (the test fails if a flag is
# neither here nor a keyword of `rkwave.Plan`).
CLI_FLAGS = {
    "samples": "Plan.add(xy, values)",
    # add takes only the new round's samples already (the earlier ones kept in memory), so
    # the command line's way of giving only those is add itself
    "new_samples": "Plan.add(xy, values)",
    "state": "Plan.save(dir) / Plan.load(dir)",
    "out": "Plan.positions()",
    "final_image": "Plan.image()",
    "force": "Plan.save(dir, overwrite=True)",
    "drop_nonfinite": "Plan.add(..., drop_nonfinite=True)",
    "json": "Plan.report",
    "help": "help(rkwave.Plan)",
    "memory_limit": "rkwave.set_memory_limit()",
}


def plan_flags(cli):
    """The long flags of `rkwave plan --help`, `-` spelled `_`."""
    _, out, _ = cli("plan", "--help")
    return {f.replace("-", "_") for f in re.findall(r"^\s+(?:-\w, )?--([a-z][a-z-]*)", out, re.M)}


def keywords(obj):
    return set(inspect.signature(obj).parameters) - {"self"}


def stubs():
    """The functions and classes of the type stubs: name -> ast node."""
    import ast

    tree = ast.parse(STUBS.read_text())
    return {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}


def stub_parameters(function):
    a = function.args
    return [x.arg for x in a.posonlyargs + a.args + a.kwonlyargs if x.arg != "self"]


def test_every_plan_flag_is_a_keyword_of_the_same_name(cli):
    flags = plan_flags(cli)
    assert {"pixel_share", "min_growth", "pattern", "spread", "tile"} <= flags, flags
    plan = keywords(rkwave.Plan)
    # each flag is a keyword of Plan, or a file of the command line's loop (CLI_FLAGS)
    assert flags - plan == set(CLI_FLAGS), (flags - plan) ^ set(CLI_FLAGS)
    # and each keyword of Plan is a flag
    assert plan <= flags, plan - flags
    # the tasks' side of rkwave.dask.TiledPlan takes Plan's keywords (tile required) and its
    # own two
    assert keywords(rkwave._rkwave.TiledPlanRounds) == plan | {"rows_per_task", "threads"}


def test_the_stubs_are_the_modules_signatures():
    """Every public name of the compiled module is in `_rkwave.pyi`, and every function and
    method there has the module's parameters, in order (the stubs are what an editor shows)."""
    import ast

    module = rkwave._rkwave
    stubbed = stubs()
    public = {n for n in dir(module) if not n.startswith("_")}
    assert public == set(stubbed), public ^ set(stubbed)
    checked = 0
    for name, node in stubbed.items():
        runtime = getattr(module, name)
        members = [(runtime, node)] if isinstance(node, ast.FunctionDef) else [
            (runtime if f.name == "__init__" else getattr(runtime, f.name), f)
            for f in node.body
            if isinstance(f, ast.FunctionDef) and f.name != "__call__"  # a slot: (*args)
            and not any(getattr(d, "id", None) == "property" for d in f.decorator_list)
        ]
        for obj, f in members:
            ours = [p for p in inspect.signature(obj).parameters if p != "self"]
            assert ours == stub_parameters(f), (name, f.name, ours, stub_parameters(f))
            checked += 1
    assert checked >= 30, checked


def cli_plan(cli, run, flags):
    """`rkwave plan` through files with disc_scene as the renderer (`flags` on the first
    call); the positions of every round, and every call's printed notes."""
    cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state", run, "--out",
        run / "n0.npy", *flags)
    positions, everything, notes, k = [np.load(run / "n0.npy")], None, [], 0
    while True:
        new = positions[-1]
        rendered = np.c_[new, disc_scene(new)]
        everything = rendered if everything is None else np.r_[everything, rendered]
        np.save(run / f"s{k}.npy", everything)
        k += 1
        _, text, _ = cli("plan", "--state", run, "--samples", run / f"s{k - 1}.npy", "--out",
                         run / f"n{k}.npy")
        # a note is printed wrapped: its words, one space apart
        notes.append(" ".join(re.sub(r"\n\s+", " ", text).split("note: ")[1:]).split())
        positions.append(np.load(run / f"n{k}.npy"))
        if len(positions[-1]) == 0:
            return positions[:-1], notes


def python_plan(plan):
    positions, notes = [], []
    while not plan.done:
        xy = plan.positions()
        positions.append(xy)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            plan.add(xy, disc_scene(xy))
        notes.append([str(w.message) for w in seen if issubclass(w.category, rkwave.RkwaveWarning)])
    return positions, notes


def test_pixel_share_gives_the_cli_positions_bit_for_bit(tmp_path, cli):
    """`pixel_share=0.5` is `--pixel-share 0.5`: the same positions every round, bit for bit,
    the same notes each round; the report counts what the share placed per round, and the
    share is not ignored (other positions than the plan without it)."""
    positions, cli_notes = cli_plan(cli, tmp_path / "run", ("--pixel-share", 0.5))
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, pixel_share=0.5)
    mine, notes = python_plan(plan)
    assert len(mine) == len(positions) > 2
    for a, b in zip(mine, positions):
        np.testing.assert_array_equal(a, b)
    placed = [s["log"]["pixel_spread"] for s in plan.report["steps"]]
    assert sum(placed) > 0, placed
    for k, (said, theirs) in enumerate(zip(notes, cli_notes)):
        share = [n for n in said if n.startswith("pixel share 0.5: ")]
        if placed[k]:
            assert len(share) == 1 and share[0].startswith(f"pixel share 0.5: {placed[k]} of"), said
        # the command line printed the same notes (wrapped; compared word by word)
        assert " ".join(" ".join(said).split()) == " ".join(theirs), (said, theirs)
    default, _ = python_plan(rkwave.Plan(resolution=(W, H), spp=SPP))
    assert any(
        len(a) != len(b) or not np.array_equal(a, b) for a, b in zip(mine, default)
    ), "pixel_share=0.5 gave the positions of the plan without it"


@pytest.mark.parametrize(
    "keyword, flag, value",
    [("pixel_share", "--pixel-share", 1.5), ("min_growth", "--min-growth", -1.0)],
)
def test_same_ranges_as_the_command_line(tmp_path, cli, keyword, flag, value):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H), spp=SPP, **{keyword: value})
    assert py_err.value.kind == "InvalidInput"
    code, _, err = cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state",
                       tmp_path / "state", "--out", tmp_path / "n0.npy", f"{flag}={value}",
                       check=False)
    assert code == 2, err
    # the refiner's own range names the parameter itself on both sides
    assert cli_error(err) == str(py_err.value)
    assert keyword in str(py_err.value)


@pytest.mark.parametrize(
    "keyword, flag, value, expected",
    [("pattern", "--pattern", "halton", "expected sobol or stratified"),
     ("spread", "--spread", "even", "expected uniform, indicator or uncertainty")],
)
def test_same_names_as_the_command_line(tmp_path, cli, keyword, flag, value, expected):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H), spp=SPP, **{keyword: value})
    assert py_err.value.kind == "InvalidInput"
    assert str(py_err.value).startswith(f'{keyword}="{value}": ')
    code, _, err = cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state",
                       tmp_path / "state", "--out", tmp_path / "n0.npy", flag, value,
                       check=False)
    assert code == 2, err
    # the library's words for the names, in both
    ours = str(py_err.value).split(": ", 1)[1]
    assert ours.endswith(expected) and ours in err, (ours, err)


def cli_tiled_refusal(cli, tmp_path):
    code, _, err = cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state",
                       tmp_path / "state", "--out", tmp_path / "n0.npy", "--tile", 16,
                       "--pixel-share", 0.5, check=False)
    assert code == 2, err
    assert not (tmp_path / "n0.npy").exists()
    return cli_error(err).replace("--pixel-share", "pixel_share=").replace("--tile", "tile=")


def test_the_tiled_plan_refuses_pixel_share_as_the_command_line(tmp_path, cli):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H), spp=SPP, tile=16, pixel_share=0.5)
    assert py_err.value.kind == "InvalidInput"
    ours = str(py_err.value)
    assert ours.startswith("pixel_share= is not available with the tiled plan"), ours
    assert ours.endswith(": drop pixel_share= or tile="), ours
    assert cli_tiled_refusal(cli, tmp_path) == ours
    # no share (0, the default) is the tiled plan as before
    assert rkwave.Plan(resolution=(W, H), spp=SPP, tile=16, pixel_share=0.0).report["tiles"]


def test_the_dask_tiled_plan_refuses_pixel_share_alike(tmp_path, cli):
    pytest.importorskip("dask")
    import rkwave.dask

    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.dask.TiledPlan((W, H), spp=SPP, tile=16, pixel_share=0.5)
    assert py_err.value.kind == "InvalidInput"
    assert str(py_err.value) == cli_tiled_refusal(cli, tmp_path)


def test_a_tiled_plan_refuses_drop_nonfinite_as_the_command_line(tmp_path, cli):
    """`add(..., drop_nonfinite=True)` on a tiled plan is refused by the library's one check,
    the words of `rkwave plan --tile ... --drop-nonfinite`; the plan is unchanged."""
    plan = rkwave.Plan(resolution=(W, H), spp=SPP, tile=16)
    xy = plan.positions()
    with pytest.raises(rkwave.RkwaveError) as py_err:
        plan.add(xy, disc_scene(xy), drop_nonfinite=True)
    assert py_err.value.kind == "InvalidInput" and plan.round == 0
    code, _, err = cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state",
                       tmp_path / "state", "--out", tmp_path / "n0.npy", "--tile", 16,
                       "--drop-nonfinite", check=False)
    assert code == 2, err
    theirs = cli_error(err).replace("--drop-nonfinite", "drop_nonfinite=True")
    assert theirs.replace("--tile", "tile=") == str(py_err.value)
    plan.add(xy, disc_scene(xy))
    assert plan.round == 1


def test_a_halo_without_tiles_is_refused_as_the_command_line(tmp_path, cli):
    with pytest.raises(rkwave.RkwaveError) as py_err:
        rkwave.Plan(resolution=(W, H), spp=SPP, halo=4)
    assert py_err.value.kind == "InvalidInput"
    code, _, err = cli("plan", "--resolution", f"{W}x{H}", "--spp", SPP, "--state",
                       tmp_path / "state", "--out", tmp_path / "n0.npy", "--halo", 4,
                       check=False)
    assert code == 2, err
    theirs = cli_error(err).replace("--tile", "tile=").replace("--halo", "halo=")
    assert theirs == str(py_err.value)
    assert str(py_err.value) == (
        "halo= is the halo of the tiles of a tiled plan: set tile= with it, or drop halo=")
