"""Three valid extremes verify at the default duration and settings.

Each once failed its own ``--verify`` in a high plate band, and a third, much tighter solve
(adaptive-modal at rtol 1e-10) showed that the verifying IDA solve was the wrong one: its
``atol_acceleration`` was the preset's absolute value, not scaled to the scene's level
(``roughness.rms = 1e-9``: 350 times quieter than ``paper``), or scaled to the louder of block
and plate (``block.mass = 1e-4``: the plate 65 dB quieter than the block). The verifying solve
now scales it as the run does, by the quieter signal. Each case must pass, or the failure says
which item of the contract broke.
"""

import pytest

import roughvib
from roughvib.api import simulate


@pytest.mark.slow
@pytest.mark.parametrize("over", [{"roughness.rms": 1e-9}, {"block.mass": 1e-4},
                                  {"plate.thickness": 0.05}],
                         ids=["rms-1e-9", "mass-1e-4", "thickness-0.05"])
def test_an_extreme_passes_its_own_verify(over):
    r = simulate(roughvib.load_scene("paper", {**over, "output.progress": False}), verify=True)
    acc = r.summary["accuracy"]
    assert acc["verdict"] == "pass", acc["failures"]
    assert acc["representation"]["verdict"] == "pass"
