"""
Quickstart: a short run
=======================

Run a shortened paper scene, look at the result, draw the block's velocity, save it. Run
with ``python examples/01_quickstart.py [OUT_DIR]``; the test suite runs it too.
"""

import sys

import roughvib
from roughvib.views.figures import plot_velocity


def main(out_dir: str = "runs/quickstart") -> roughvib.Result:
    # the built-in paper scene (0.221 kg, 10 mm/s rms at 7 Hz, four contact points from
    # the contact module, modes to 50 kHz), shortened to two excitation periods (2/7 s: one of
    # run-in, one analysed) and with fewer plate modes so that it runs in seconds
    scene = roughvib.load_scene("paper", **{"output.duration": 2 / 7,
                                            "plate.max_frequency": 10e3,
                                            "output.progress": False})
    result = roughvib.simulate(scene)
    ds = result.to_dataset()
    acc = ds["block_vertical_acceleration"]
    print(f"status: {result.status}; T0 = {result.summary['force_amplitude']:.4f} N")
    print(f"block acceleration rms: {float((acc**2).mean()) ** 0.5:.4g} {acc.attrs['units']}")
    print(f"events: {len(result.events)} ({', '.join(result.events['kind'].unique())})")
    print(f"energy audit relative residual: "
          f"{result.summary['energy_audit']['relative_residual']:.2e}")
    # the block's tangential velocity: it sticks (grey) twice per period (the paper's Fig. 6);
    # `roughvib report OUT_DIR` draws this and every other figure of the run
    plot_velocity(result)
    result.save(out_dir)
    print(f"saved to {out_dir}")
    return result


if __name__ == "__main__":
    main(*sys.argv[1:2])
