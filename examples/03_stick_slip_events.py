"""
Stick and slip phases in the event log
======================================

Every change of regime is an event of the run: the start of a stick phase (the block's speed
falls below ``friction.stick_velocity``, 0.5 mm/s), the start of a slip phase, a change of the
friction-law branch, a flip of the hysteresis latch, a contact lifting off or touching down.
The event log, a :class:`pandas.DataFrame`, records each with its time and the regime before
and after. This example runs one excitation period (1/7 s) of the paper scene at 10 mm/s,
where the block sticks twice per period. To keep it short, the plate modes are cut at 2 kHz
(stick and slip are set by the tangential motion, which the top modes hardly touch) and it
uses ``adaptive-modal``, the fast event-driven solver, whose event log is IDA's (same regimes,
same event kinds, event times within 1e-7 s of IDA's in the tests).
"""

import matplotlib.pyplot as plt

import roughvib
from roughvib.analysis.events import phase_table, stick_intervals
from roughvib.views.figures import plot_events

scene = roughvib.load_scene("paper", {"output.duration": 1 / 7, "output.transient": 0.0,
                                      "plate.max_frequency": 2000.0,
                                      "solver.method": "adaptive-modal",
                                      "output.progress": False})
result = roughvib.simulate(scene)
events = result.events
print(events["kind"].value_counts().to_string())

# %%
# The stick and slip events, with the regime before and after each. The regime reads
# ``closed=...`` (one digit per contact: 1 closed, 0 lifted off), ``b`` the friction-law
# branch, ``s`` the hysteresis latch, and the phase.
phases = events[events["kind"].isin(["stick", "slip"])]
print(phases[["time", "kind", "tangential_velocity", "regime_after"]].to_string(index=False))

# %%
# Stick intervals from the log, and the per-period phase table that ``roughvib events``
# prints.
t_end = float(result.dataset["time"][-1])
for start, end in stick_intervals(events, t_end):
    print(f"stick from {start * 1e3:7.2f} ms to {end * 1e3:7.2f} ms ({(end - start) * 1e3:.1f} ms)")
n_contacts = int(result.dataset.sizes["contact"])  # contact.points may be "auto"
table = phase_table(events, t_end, scene.period, n_contacts)
print(table[["cycle", "stick_fraction", "stick_phases", "mean_stick_duration"]].to_string())

# %%
# The regime timeline over the tangential velocity and the normal force: shaded where the
# block sticks, one mark per event.
plot_events(result)
plt.show()
