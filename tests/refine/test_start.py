"""A refinement started from given commands (``refine_commands(start=…)``, ``library refine
--start refined``): the user refines a library on the spec's twin, calibrates the twin from a
log, and refines again from where the first refinement ended.

Oracles: the cost the first refinement reported for its commands (the start, mapped back to
openings, must cost the same on the same twin), the nominal commands' cost (a start that
prices higher is not taken), and the library's own records of what each entry started from."""
import re
import shutil
from dataclasses import replace

import numpy as np
import pytest

from planner.library.refine import refine_library
from planner.library.refined import read_refined
from planner.library.store import LibraryStore
from planner.model.twin import Twin
from planner.refine import RefineOptions, RefineStatus, refine_commands
from tests.library.helpers import move_library

OPTS = RefineOptions(iterations=6, settle=1.0, rest_window=0.5, calm=0.0, time_entries="plain",
                     restart_iterations=0)   # the restart: its own test


@pytest.fixture(scope="module")
def first(umea_move):
    crane, move, t_u, u = umea_move
    return refine_commands(crane, move, t_u, u, twin=Twin(crane), options=OPTS)


def test_a_start_from_an_earlier_refinement_costs_what_it_cost_and_is_never_worsened(
        umea_move, first):
    crane, move, t_u, u = umea_move
    assert first.status == RefineStatus.IMPROVED, first.reason
    again = refine_commands(crane, move, t_u, u, twin=Twin(crane),
                            options=replace(OPTS, iterations=2), start=(first.t_u, first.u))
    began = again.predicted["start"]
    assert began["commands"] == "given"
    # the start is the first refinement's commands exactly (openings, dead bands, the tail)
    assert began["cost"] == pytest.approx(first.predicted["cost_refined"], rel=1e-6)
    assert again.predicted["cost_refined"] <= began["cost"] * (1 + 1e-9)
    assert again.predicted["cost_nominal"] == pytest.approx(first.predicted["cost_nominal"],
                                                            rel=1e-9)
    cold = refine_commands(crane, move, t_u, u, twin=Twin(crane),
                           options=replace(OPTS, iterations=2))
    assert cold.predicted["start"] == {"commands": "nominal"}
    assert again.predicted["cost_refined"] < cold.predicted["cost_refined"]


def test_a_start_that_prices_above_the_nominal_commands_is_not_taken(umea_move):
    crane, move, t_u, u = umea_move
    shut = np.zeros_like(u)         # every valve closed: the crane never moves
    r = refine_commands(crane, move, t_u, u, twin=Twin(crane),
                        options=replace(OPTS, iterations=1), start=(t_u, shut))
    assert r.predicted["start"]["commands"].startswith("nominal (the given priced higher)")
    assert r.predicted["start"]["cost"] > r.predicted["cost_nominal"]


def test_a_given_start_predicted_off_is_refined_again_from_the_nominal_commands(
        umea_move, first):
    """Where the move refined from a given start is predicted off (above fallback_above), it
    is refined again from the nominal commands and the better landing by the twin is kept,
    both recorded and both paid for; a start not taken (priced higher) is retried only with
    more iterations than the first search had."""
    from planner.refine.measures import score
    crane, move, t_u, u = umea_move
    opts = replace(OPTS, iterations=2, fallback_above=1e-9,     # every move counts as off
                   restart_iterations=2)
    r = refine_commands(crane, move, t_u, u, twin=Twin(crane), options=opts,
                        start=(first.t_u, first.u))
    rs = r.predicted["restart"]
    assert rs["nominal_status"] == str(RefineStatus.IMPROVED)
    cold = refine_commands(crane, move, t_u, u, twin=Twin(crane), options=opts)
    assert "restart" not in cold.predicted
    assert rs["nominal"] == pytest.approx(cold.predicted["refined"], rel=1e-9)
    best = min(score(rs["first"]), score(rs["nominal"]))
    assert score(r.predicted["refined"]) == pytest.approx(best, rel=1e-12)
    assert r.predicted["start"]["commands"] == ("nominal" if rs["taken"] else "given")
    assert r.iterations > rs["nominal_iterations"]       # both searches are counted
    shut = refine_commands(crane, move, t_u, u, twin=Twin(crane), options=opts,
                           start=(t_u, np.zeros_like(u)))
    assert "restart" not in shut.predicted      # the same search again: not repeated
    assert shut.predicted["start"]["commands"].startswith("nominal (the given priced higher)")
    # priced higher with the warm start's fewer iterations: the nominal search with more
    longer = refine_commands(crane, move, t_u, u, twin=Twin(crane),
                             options=replace(opts, restart_iterations=3),
                             start=(t_u, np.zeros_like(u)))
    assert longer.predicted["restart"]["nominal_iterations"] > 0


def test_the_restart_is_the_whole_refinement_and_its_record_survives_the_landing_fallback(
        umea_move, first):
    """A priced refinement predicted off takes the landing-first fallback (the move without
    the price); the restart from the nominal commands is that whole refinement again — its own
    fallback included — and its record is kept whichever of them lands better."""
    crane, move, t_u, u = umea_move
    opts = replace(OPTS, iterations=2, fallback_above=1e-9, restart_iterations=3,
                   energy_weight=1.0)
    r = refine_commands(crane, move, t_u, u, twin=Twin(crane), options=opts,
                        start=(first.t_u, first.u))
    rs = r.predicted["restart"]
    cold = refine_commands(crane, move, t_u, u, twin=Twin(crane),
                           options=replace(opts, iterations=3))
    assert "fallback" in cold.predicted          # the cold refinement's own fallback ran
    assert rs["nominal"] == pytest.approx(cold.predicted["refined"], rel=1e-9)
    if rs["taken"]:
        assert "fallback" in r.predicted


def test_a_start_off_the_command_grid_is_refused_with_its_shape(umea_move):
    crane, move, t_u, u = umea_move
    with pytest.raises(ValueError, match=r"start commands of shape \(\d+, 2\)"):
        refine_commands(crane, move, t_u, u, twin=Twin(crane), options=OPTS,
                        start=(t_u, u[:, :2]))
    with pytest.raises(ValueError, match="50 Hz grid"):
        refine_commands(crane, move, t_u, u, twin=Twin(crane), options=OPTS,
                        start=(t_u + 0.01, u))


@pytest.fixture(scope="module")
def lib(tmp_path_factory, umea_move):
    path = tmp_path_factory.mktemp("start") / "lib.h5"
    move_library(path, umea_move[0], [(0.35, 0.6), (0.6, 0.4)], scale=0.8).close()
    return path


def test_library_refine_on_another_twin_starts_from_the_stored_refinement(lib, tmp_path):
    path = tmp_path / "lib.h5"
    shutil.copy(lib, path)
    opts = replace(OPTS, iterations=3)
    first = refine_library(path, options=opts, show_progress=False)
    assert first["refined"] == 2 and first["started_from_refined"] == 0
    with LibraryStore.open(path) as db:
        before = {i: read_refined(db, i) for i in db.ids()}
        text = db.spec_toml
    # a "calibrated" spec of the same machine: its oil a third softer
    m = re.search(r"^bulk_modulus\s*=\s*([0-9.eE+]+)", text, re.M)
    model = tmp_path / "soft.toml"
    model.write_text(text[:m.start(1)] + repr(float(m.group(1)) * 0.7) + text[m.end(1):])
    s = refine_library(path, model=model, options=opts, show_progress=False, start="refined")
    assert s["refined"] == 2 and s["started_from_refined"] == 2
    with LibraryStore.open(path) as db:
        for i in db.ids():
            info = read_refined(db, i)[2]
            assert info["predicted"]["start"]["commands"] in (
                "given", "nominal (the given priced higher)")
            assert info["model"]["fingerprint"] != before[i][2]["model"]["fingerprint"]
    assert s["restarted"] == 0          # restart_iterations = 0
    # every entry counted off: those that took their given start are refined again from the
    # nominal commands, counted in the summary and recorded per entry
    again = replace(opts, fallback_above=1e-9, restart_iterations=1)
    s = refine_library(path, model=model, options=again, show_progress=False, start="refined",
                       force=True)
    with LibraryStore.open(path) as db:
        infos = [read_refined(db, i)[2]["predicted"] for i in db.ids()]
    assert s["restarted"] == sum("restart" in p for p in infos) > 0
    assert s["restart_taken"] == sum(p["restart"]["taken"] for p in infos if "restart" in p)
    with pytest.raises(ValueError, match="start = 'best'; allowed: nominal, refined"):
        refine_library(path, options=opts, show_progress=False, start="best")


def test_cli_refuses_a_refined_start_for_a_cycle(lib, tmp_path, capsys):
    from planner.cli import main
    path = tmp_path / "lib.h5"
    shutil.copy(lib, path)
    assert main(["library", "refine", str(path), "--cycle", "m0:time,m1:time",
                 "--start", "refined"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--start refined" in err[0] and "--cycle" in err[0]
