"""The vocabulary of the event log: the event kinds and the notation of the regime columns.

A leaf module (plain strings, no imports), so that the command-line help and every stage may
use it; :mod:`roughvib.results` re-exports both names next to the event-log columns.
"""

__all__ = ["EVENT_KINDS", "REGIME_NOTATION"]

#: event kind -> meaning: every kind a solver writes into the event log
EVENT_KINDS: dict[str, str] = {
    "lift_off": "a contact opens (its spring force reaches zero)",
    "touch_down": "an open contact closes again (it touches the surface)",
    "stick": "the block starts to stick",
    "slip": "the block starts to slide (also a reversal of the sliding direction)",
    "friction_branch": "Feldmann law: the branch b = sign(v + s v_h) changes",
    "latch_flip": "Feldmann law: the hysteresis latch s flips at a velocity extremum",
    "hysteresis_hold": "guard (Coulomb law): stick held within "
                       "friction.parameters.switching_hysteresis above mu_stick F_N",
    "dwell_hold": "guard (Coulomb law): break-away held until friction.parameters.dwell_time "
                  "in stick",
    "chatter_guard": "guard (Coulomb law): stick held for friction.parameters.chatter_window "
                     "after more than friction.parameters.chatter_switches stick/slip "
                     "switches within that window",
    "event_storm": "guard: too many events within solver.event_window; the run stops",
}

#: how the regime_before / regime_after columns of the event log read
REGIME_NOTATION = """\
regime columns (regime_before, regime_after; empty for the fixed-step schemes):
  closed=1111011111 b=+1 s=-1 slip   Feldmann friction law
  closed=111 slip+                   Coulomb law (stick, slip+ or slip-)
  closed=...  one digit per contact, contact 0 first: 1 closed (touching,
              spring loaded), 0 open (lifted off)
  b=+1/-1     branch of the Feldmann law: the sign of v + s v_h (v the block's
              tangential velocity, v_h = friction.parameters.hysteresis_velocity)
  s=+1/-1     hysteresis latch: +1 after a velocity maximum (decelerating),
              -1 after a velocity minimum (accelerating)
  stick/slip  the block's phase: stick while |v| < friction.stick_velocity
              (Coulomb law: v held at zero); slip+ / slip- give the direction
  With prescribed tangential motion there is no friction model: read closed= only.
result.nc holds the same states as time series: contact_closed(time, contact)
and stick(time)."""
