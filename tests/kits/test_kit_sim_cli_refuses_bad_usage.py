"""``overdrive kit-sim pacmod3`` refuses bad usage with exit 2 and one line before it opens a
bus: a malformed ``--fault``, a vehicle without a steering ratio, an unknown vehicle."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.run.kit_sim import parse_fault

BUS = ("--can-interface", "virtual", "--can-channel", "kit-sim-cli")


@pytest.mark.parametrize("args, words", [
    (("--fault", "override:brake"), "KIND:SYSTEM:START"),
    (("--fault", "override:brake:x"), "numbers"),
    (("--fault", "melt:brake:1"), "kind"),
    (("--fault", "override::1"), "names its system"),
    (("--fault", "override:brake:1:2:1.5"), "ratio 0..1"),
    (("--fault", "override:brake:2:1:0.5"), "after its start"),
    (("--fault", "stuck:shift:1"), "accel, brake or steering"),
    (("--fault", "override:brake:nan"), "finite"),
    (("--vehicle", "escape-hybrid"), "steering_ratio"),
    (("--vehicle", "no-such-preset"), "unknown vehicle preset"),
])
def test_bad_usage_is_exit_2_naming_the_problem(args: tuple[str, ...], words: str) -> None:
    result = CliRunner().invoke(main, ["kit-sim", "pacmod3", *BUS, *args, "--duration", "0.1"])
    assert result.exit_code == 2, result.output
    assert words in result.output


def test_a_good_fault_is_on_the_scenario_clock() -> None:
    fault = parse_fault("override:steering:5:7:4.0")
    assert (fault.kind, fault.system, fault.start_s, fault.end_s, fault.value) == (
        "override", "steering", 5.0, 7.0, 4.0)
    assert parse_fault("silence::3:4").system is None
    assert parse_fault("stuck:brake:2").end_s is None

