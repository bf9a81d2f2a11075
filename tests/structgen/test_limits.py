"""A numeric setting's range and meaning live in one place (its class's ``limits``): the check of the settings, the
command-line option made from it and its help all read them."""

from __future__ import annotations

import dataclasses
import math

import pytest

from structgen.cli import main
from structgen.config import Limit, check_limits, limits_of
from structgen.domains.autoverse.problem import AutoverseSettings
from structgen.domains.autoverse.train_settings import TrainSettings
from structgen.domains.fortress.problem import FortressSettings
from structgen.domains.layouts.maze.agent_settings import AgentSettings
from structgen.domains.layouts.problem import ManufacturingSettings, MazeSettings, WarehouseSettings
from structgen.domains.structures.problem import StructuresSettings
from structgen.domains.structures.tall_settings import TallSettings
from structgen.mesh import MeshStyle
from structgen.nca_config import NCAConfig
from structgen.ppo_settings import PPOSettings

#: The settings classes whose ranges live in limits.
SETTINGS = (
    PPOSettings,
    AgentSettings,
    TrainSettings,
    NCAConfig,
    WarehouseSettings,
    ManufacturingSettings,
    MazeSettings,
    MeshStyle,
    TallSettings,
    FortressSettings,
    StructuresSettings,
    AutoverseSettings,
)


def test_a_subclass_adds_to_its_bases_limits_and_its_own_entries_win():
    agent, ppo = limits_of(AgentSettings), limits_of(PPOSettings)
    assert set(ppo) < set(agent) and "size" in agent and "epochs" in agent
    assert agent["epochs"] is ppo["epochs"]
    assert ppo["updates"].low == 0 and agent["updates"].low == 1  # a training of no update is no training of an agent


@pytest.mark.parametrize("settings", SETTINGS, ids=lambda cls: cls.__name__)
def test_every_default_is_inside_its_own_limit(settings):
    defaults = settings()
    for name, limit in limits_of(settings).items():
        assert name in {field.name for field in dataclasses.fields(settings)}, name
        assert limit.admits(getattr(defaults, name)), (name, getattr(defaults, name), limit.describe())


@pytest.mark.parametrize(
    ("settings", "field", "value", "message"),
    [
        (AgentSettings, "replay", 2.0, "agent replay = 2.0: expected a number from 0 to 1"),
        (AgentSettings, "updates", 0, "agent updates = 0: expected a whole number from 1 to 10,000,000"),
        (AgentSettings, "size", 3.5, "agent size = 3.5: expected a whole number from 4 to 256"),
        (TrainSettings, "clone_learning_rate", 0.0, "train clone_learning_rate = 0.0: expected a number above 0, at most 1"),
        (TrainSettings, "min_fitness", math.nan, "train min_fitness = nan: expected a number"),
        (PPOSettings, "epochs", True, "ppo epochs = True: expected a whole number from 1 to 1,000"),
    ],
)
def test_a_setting_outside_its_limit_names_itself_its_value_and_the_range(settings, field, value, message):
    with pytest.raises(ValueError) as refused:
        settings(**{field: value})
    assert str(refused.value) == message


def test_the_command_line_option_is_made_from_the_limit(capsys):
    with pytest.raises(SystemExit) as done:
        main(["maze", "train", "--help"])
    shown = capsys.readouterr().out
    assert done.value.code == 0
    assert "--replay X" in shown and "replayed from the buffer (default 0.5)" in shown.replace("\n", " ").replace("  ", " ")
    for argv, message in (
        (
            ["maze", "train", "--run-dir", "never-made", "--replay", "2"],
            "argument --replay: expected a number from 0 to 1, got 2",
        ),
        (["autoverse", "train", "run", "-o", "never-made", "--clone-lr", "0"], "argument --clone-lr: expected a number above 0"),
    ):
        with pytest.raises(SystemExit) as done:
            main(argv)
        assert done.value.code == 2 and message in capsys.readouterr().err


def test_check_limits_reads_the_limits_of_any_settings_class():
    @dataclasses.dataclass(frozen=True)
    class Dice:
        section = "dice"
        limits = {"sides": Limit(2, 100, "faces of a die")}
        sides: int = 6

        def __post_init__(self) -> None:
            check_limits(self)

    assert Dice(20).sides == 20
    with pytest.raises(ValueError, match=r"^dice sides = 1: expected a whole number from 2 to 100$"):
        Dice(1)


def test_a_whole_number_of_any_size_is_judged_by_its_range_not_by_float_overflow():
    from structgen.registry.commands import whole_number

    huge = 10**400
    assert not Limit(0, 10, "").admits(huge) and Limit(0, math.inf, "").admits(huge)
    with pytest.raises(Exception, match="expected a whole number from 0 to 5, got 10,000,000"):
        whole_number(0, 5)(str(huge))
