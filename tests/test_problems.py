"""planner.problems locates the shipped machines and task suites (package data); the model and
the task layer read them. Ids, paths given instead of ids, and the errors for unknown ones."""
import shutil

import pytest

from planner.model import Crane, load_crane
from planner.problems import CRANES, crane_file, crane_ids, crane_path, task_ids, task_path
from planner.tasks.suites import load_suite

# the machines and suites of the seed documents (README, docs/design.md)
SHIPPED_CRANES = ["cat215b", "cranab850", "s100f", "umea-lab"]
SHIPPED_SUITES = ["forwarder-cycle", "seed000-abc", "seed002-hvd", "seed003-paths"]


def test_the_shipped_ids():
    assert crane_ids() == SHIPPED_CRANES and task_ids() == SHIPPED_SUITES
    assert CRANES.parent.name == "problems" and CRANES.parent.parent.name == "planner"


def test_an_id_and_a_path_name_the_same_file(tmp_path):
    assert crane_file("umea-lab") == crane_path("umea-lab") == CRANES / "umea-lab.toml"
    mine = tmp_path / "my-crane.toml"
    shutil.copy(crane_path("umea-lab"), mine)
    assert crane_file(str(mine)) == mine                 # the path as given
    assert load_crane(str(mine)).joint_names == load_crane("umea-lab").joint_names
    assert Crane.from_id(str(mine)).names == Crane.from_id("umea-lab").names


@pytest.mark.parametrize("bad", ["nope", "no-such.toml", "umea-lab.TOML"])
def test_an_unknown_crane_lists_the_known_ids(bad):
    with pytest.raises(KeyError) as info:
        crane_file(bad)
    msg = info.value.args[0]
    assert f"unknown crane '{bad}'" in msg and all(c in msg for c in SHIPPED_CRANES)


def test_task_suites_by_name_and_by_path(tmp_path):
    assert task_path("seed000-abc").name == "seed000-abc.toml"
    copy = tmp_path / "abc.toml"
    shutil.copy(task_path("seed000-abc"), copy)
    assert task_path(str(copy)) == copy
    ids = [[m.id for m in load_suite(name)[1]] for name in (str(copy), "seed000-abc")]
    assert ids[0] == ids[1] and len(ids[0]) >= 3
    with pytest.raises(KeyError, match="unknown task suite 'nope'; known: forwarder-cycle"):
        task_path("nope")
