"""Each friction law's regimes: its start, its three friction roots' transitions, their names.

``model.regimes`` switches the contacts and hands the friction roots to the registered law
(``LAWS[law].initial``, ``.transition``, ``.roots``); the law modules read plain values
(``physics.friction.regime``). The decisions are checked against their closed forms: the
static bound ``|T_exc| <= mu_stick F_N`` on both sides, the chatter guard past
``chatter_switches`` switches within ``chatter_window``, the Feldmann branch/latch/phase flips.
"""

import ast
import dataclasses
import inspect
import math
import pickle
import textwrap

import numpy as np
import pytest

from roughvib.model import kernels as kn
from roughvib.model import regimes
from roughvib.model.regimes import NO_DWELL, Regime, initial_regime, switch
from roughvib.physics.friction import LAWS, feldmann, setvalued
from roughvib.physics.friction import regime as fr

MU_ST = 0.6
F_N = 3.0  # N, so the static bound mu_stick F_N is 1.8 N


def _at(t=0.0, vx=0.0, texc=0.0, fsum=F_N, hyst=0.0, r2=0.0, dwell=0.0, n_chatter=0,
        window=0.0):
    return fr.RootValues(t=t, vx=vx, exciting_force=texc, normal_force=fsum, mu_stick=MU_ST,
                         hysteresis=hyst, r2=r2, dwell_time=dwell, chatter_switches=n_chatter,
                         chatter_window=window)


def _regime(law, **kw):
    return Regime(closed=np.ones(3, dtype=np.int64), law=law, **kw)


def _fp(t0=0.0, omega=0.0, vh=0.0, hyst=0.0, r2=0.0, mass=1.0, grav=9.81):
    fp = np.zeros(kn.N_FP)
    fp[kn.FP_T0], fp[kn.FP_OMEGA], fp[kn.FP_VH], fp[kn.FP_HYST] = t0, omega, vh, hyst
    fp[kn.FP_R2], fp[kn.FP_MASS], fp[kn.FP_GRAV], fp[kn.FP_MU_STICK] = r2, mass, grav, MU_ST
    return fp


# ---- registration ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(LAWS))
def test_every_law_registers_its_start_transitions_and_root_names(name):
    law = LAWS[name]
    assert len(law.roots) == fr.N_ROOTS == kn.N_LAW_ROOTS
    assert all(isinstance(r, str) and r for r in law.roots)
    assert len(set(law.roots)) == len(law.roots)
    # the law's physics: functions of the friction package, not of the model
    for fn in (law.initial, law.transition):
        assert callable(fn) and fn.__module__.startswith("roughvib.physics.friction.")
    # a root the law does not have is refused, not taken for another
    with pytest.raises(ValueError, match="no friction root 3"):
        law.transition(_regime(name), 3, _at())


def test_the_set_valued_laws_share_their_regimes_and_the_others_have_their_own():
    assert LAWS["coulomb"].transition is LAWS["table"].transition is setvalued.regime_transition
    assert LAWS["coulomb"].initial is LAWS["table"].initial is setvalued.regime_at_start
    assert LAWS["feldmann"].transition is feldmann.regime_transition
    others = {LAWS[n].transition for n in LAWS if not LAWS[n].set_valued and n != "feldmann"}
    assert feldmann.regime_transition not in others and setvalued.regime_transition not in others


def test_the_model_no_longer_branches_on_the_kind_for_the_friction_physics():
    for fn in (regimes.switch, regimes.initial_regime):
        names = {n.attr if isinstance(n, ast.Attribute) else n.id
                 for n in ast.walk(ast.parse(textwrap.dedent(inspect.getsource(fn))))
                 if isinstance(n, ast.Attribute | ast.Name)}
        assert not names & {"set_valued", "kind", "KIND_SET_VALUED"}
        assert "transition" in names or "initial" in names
    assert regimes.Transition is fr.Transition and regimes.NO_DWELL == fr.NO_DWELL


def test_an_unregistered_law_raises_instead_of_falling_through():
    fp = _fp(t0=1.0)
    with pytest.raises(ValueError, match="'nonesuch': no law is registered"):
        initial_regime(np.ones(2), fp, True, "nonesuch")
    reg = _regime("nonesuch")
    y = np.zeros(4)
    with pytest.raises(ValueError, match="no law is registered"):
        switch(reg, 2, 0.0, y, fp, 2, 0, slice(1, 3), 0.0)
    with pytest.raises(ValueError, match="no law is registered"):
        reg.describe()


def test_switch_hands_the_friction_root_and_the_values_at_it_to_the_law(monkeypatch):
    seen = []

    def record(regime, j, at):
        seen.append((j, at))
        return []

    monkeypatch.setitem(LAWS, "feldmann", dataclasses.replace(LAWS["feldmann"],
                                                                transition=record))
    K, t, omega = 3, 0.25, math.pi / 3  # cos(omega t) = cos(pi / 12)
    y = np.array([0.7, 1.0, 2.0, 50.0])  # vx, then the contact forces
    reg = Regime(closed=np.array([1, 1, 0]), law="feldmann")  # the third is open
    assert switch(reg, K + 2, t, y, _fp(t0=4.0, omega=omega, hyst=0.1, r2=2.0), K, 0,
                  slice(1, 4), 1e-3, 5, 2e-3) == []
    (j, at), = seen
    assert j == 2 and at.t == t and at.vx == 0.7
    assert at.normal_force == 3.0  # the open contact's force is not counted
    assert at.exciting_force == pytest.approx(4.0 * math.cos(math.pi / 12), rel=1e-15)
    assert (at.mu_stick, at.hysteresis, at.r2) == (MU_ST, 0.1, 2.0)
    assert (at.dwell_time, at.chatter_switches, at.chatter_window) == (1e-3, 5, 2e-3)
    # a contact root stays the model's: the law is not asked
    assert switch(reg, 2, t, y, _fp(), K, 0, slice(1, 4), 0.0)[0].kind == "touch_down"
    assert len(seen) == 1 and reg.closed[2] == 1


# ---- the set-valued laws ------------------------------------------------------------------------


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_velocity_zero_sticks_exactly_within_the_static_bound(direction, sign):
    bound = MU_ST * F_N
    for texc, sticks in ((sign * bound * (1 - 1e-12), True), (sign * bound, True),
                         (sign * bound * (1 + 1e-12), False), (0.0, True)):
        reg = _regime("coulomb", branch=direction, stick=False)
        out = setvalued.regime_transition(reg, 0, _at(t=1.0, texc=texc))
        assert [tr.kind for tr in out] == ["stick" if sticks else "slip"]
        assert reg.branch == (0 if sticks else int(sign)) and reg.stick is sticks


def test_in_slip_only_the_velocity_zero_switches():
    for j in (1, 2):
        reg = _regime("table", branch=1, stick=False)
        assert setvalued.regime_transition(reg, j, _at(texc=0.0)) == []
        assert reg.branch == 1 and not reg.stick and reg.switch_times == []


def test_break_away_follows_the_exciting_force_and_the_guards_hold_it():
    reg = _regime("coulomb", branch=1, stick=False)
    out = setvalued.regime_transition(reg, 0, _at(t=1.0, dwell=0.01))
    assert [tr.kind for tr in out] == ["stick"] and reg.dwell_end == 1.0 + 0.01
    held = setvalued.regime_transition(reg, 0, _at(t=1.005, texc=-5.0))
    assert [(tr.kind, tr.guard) for tr in held] == [("dwell_hold", "dwell")] and reg.branch == 0
    hyst = setvalued.regime_transition(reg, 1, _at(t=1.006, texc=-5.0))
    assert [(tr.kind, tr.guard) for tr in hyst] == [("hysteresis_hold", "hysteresis")]
    # the timer expires below the bound with the hysteresis: stays in stick, hold released
    bound = MU_ST * F_N * (1 + 0.2)
    assert setvalued.regime_transition(reg, 2, _at(t=1.01, texc=bound, hyst=0.2)) == []
    assert reg.branch == 0 and reg.dwell_end == NO_DWELL
    # the break-away margin fires: slips in the direction of the force, counted as a switch
    out = setvalued.regime_transition(reg, 0, _at(t=1.02, texc=-5.0))
    assert [tr.kind for tr in out] == ["slip"] and reg.branch == -1 and not reg.stick
    assert reg.switch_times == [1.0, 1.02]


def test_the_dwell_timer_breaks_away_at_once_past_the_bound_with_the_damping():
    # the force that holds the block is lambda = T_exc - r2 v (the kernels' stick force);
    # break-away when |lambda| > mu_stick F_N (1 + hysteresis)
    lam_bound = MU_ST * F_N * (1 + 0.1)
    for texc, vx, slips in ((lam_bound + 0.5, 0.5 + 1e-9, False),  # T_exc past, lambda not
                            (lam_bound + 0.5, 0.5 - 1e-9, True),
                            (-lam_bound * (1 - 1e-9), 0.0, False),
                            (-lam_bound * (1 + 1e-9), 0.0, True)):
        reg = _regime("coulomb", branch=0, dwell_end=2.0)
        out = setvalued.regime_transition(reg, 2, _at(t=2.0, texc=texc, vx=vx, r2=1.0,
                                                      hyst=0.1))
        assert reg.dwell_end == NO_DWELL
        assert [tr.kind for tr in out] == (["slip"] if slips else [])
        assert reg.branch == (int(math.copysign(1, texc)) if slips else 0)


def _chatter_sequence(times, n_chatter, window):
    """Alternate velocity-zero sticks and break-aways at ``times``; the guards that acted."""
    reg = _regime("coulomb", branch=1, stick=False)
    guards = []
    for i, t in enumerate(times):
        if reg.branch != 0:
            out = setvalued.regime_transition(reg, 0, _at(t=t, n_chatter=n_chatter,
                                                          window=window))
            guards.append([tr.guard for tr in out if tr.guard])
        else:
            reg.dwell_end = NO_DWELL  # the previous chatter hold, if any, is over
            setvalued.regime_transition(reg, 0, _at(t=t, texc=10.0 * (-1) ** i))
    return reg, guards


def test_the_chatter_guard_engages_only_past_the_switch_count_within_its_window():
    window = 1e-3
    # switches 1e-4 s apart: the 3rd within the window engages with chatter_switches = 2
    reg, guards = _chatter_sequence([0.0, 1e-4, 2e-4], 2, window)
    assert guards == [[], ["chatter"]] and reg.dwell_end == pytest.approx(2e-4 + window)
    # with chatter_switches = 3 the same three switches do not
    assert _chatter_sequence([0.0, 1e-4, 2e-4], 3, window)[1] == [[], []]
    # switches farther apart than the window never pile up
    assert _chatter_sequence([0.0, 0.6e-3, 1.2e-3, 1.8e-3, 2.4e-3], 2, window)[1] == \
        [[], [], []]
    # off (chatter_switches = 0): never, and a stick keeps only its own switch time
    reg, guards = _chatter_sequence([0.0, 1e-5, 2e-5, 3e-5, 4e-5], 0, window)
    assert guards == [[], [], []] and reg.dwell_end == NO_DWELL
    assert reg.switch_times == [4e-5]


@pytest.mark.parametrize("hyst", [0.0, 0.25])
def test_set_valued_start_sticks_within_the_static_bound_with_the_hysteresis(hyst):
    mass, grav = 2.0, 9.81
    bound = MU_ST * mass * grav * (1 + hyst)
    for t0, branch in ((0.999 * bound, 0), (-0.999 * bound, 0), (1.001 * bound, 1),
                       (-1.001 * bound, -1)):
        for law in ("coulomb", "table"):
            reg = initial_regime(np.ones(2), _fp(t0=t0, hyst=hyst, mass=mass, grav=grav),
                                 True, law)
            assert reg.branch == branch and reg.stick is (branch == 0)
            assert reg.describe() == "closed=11 " + {0: "stick", 1: "slip+", -1: "slip-"}[branch]


# ---- the Feldmann law and the dynamic law -------------------------------------------------------


def test_feldmann_flips_branch_latch_and_phase_and_records_the_extremum():
    reg = _regime("feldmann", branch=1, latch=-1, v_ext=0.0, stick=True)
    assert [tr.kind for tr in feldmann.regime_transition(reg, 0, _at(vx=0.3))] == \
        ["friction_branch"]
    assert (reg.branch, reg.latch, reg.v_ext, reg.stick) == (-1, -1, 0.0, True)
    assert [tr.kind for tr in feldmann.regime_transition(reg, 1, _at(vx=0.3))] == ["latch_flip"]
    assert (reg.branch, reg.latch, reg.v_ext) == (-1, 1, 0.3)
    assert [tr.kind for tr in feldmann.regime_transition(reg, 1, _at(vx=-0.2))] == \
        ["latch_flip"]
    assert (reg.latch, reg.v_ext) == (-1, -0.2)
    kinds = [feldmann.regime_transition(reg, 2, _at())[0].kind for _ in range(2)]
    assert kinds == ["slip", "stick"] and reg.stick
    assert all(not tr.guard for tr in feldmann.regime_transition(reg, 0, _at()))


@pytest.mark.parametrize(("t0", "vh", "latch", "branch"), [
    (5.0, 1e-3, -1, -1),   # accelerating latch, X0 = -v_h < 0
    (-5.0, 1e-3, 1, 1),    # the mirror image
    (5.0, 0.0, -1, 1),     # no shift: the sign of T0
    (-5.0, 0.0, 1, -1),
])
def test_feldmann_start(t0, vh, latch, branch):
    reg = initial_regime(np.ones(2), _fp(t0=t0, vh=vh), True, "feldmann")
    assert (reg.latch, reg.branch, reg.v_ext, reg.stick) == (latch, branch, 0.0, True)
    assert reg.describe() == f"closed=11 b={branch:+d} s={latch:+d} stick"


def test_the_dynamic_law_switches_the_velocity_sign_and_phase_and_has_no_latch():
    name, = (n for n in LAWS if LAWS[n].kind == "dynamic")
    law = LAWS[name]
    reg = _regime(name, branch=1, latch=-1, stick=True)
    assert [tr.kind for tr in law.transition(reg, 0, _at(vx=-1e-9))] == ["friction_branch"]
    assert reg.branch == -1
    assert law.transition(reg, 1, _at(vx=0.5)) == []  # a constant margin: nothing to switch
    assert (reg.latch, reg.v_ext) == (-1, 0.0)
    assert [tr.kind for tr in law.transition(reg, 2, _at())] == ["slip"] and not reg.stick
    # the first motion follows T0, whatever v_h is packed
    for t0, b in ((3.0, 1), (-3.0, -1)):
        start = initial_regime(np.ones(2), _fp(t0=t0, vh=1e-3), True, name)
        assert start.branch == b and start.stick and start.law == name


# ---- the regime without tangential dynamics, and pickles ------------------------------------


def test_without_tangential_dynamics_there_is_no_friction_regime():
    reg = initial_regime(np.array([1, 0]), _fp(t0=100.0), False, "coulomb")
    assert reg.law is None and not reg.set_valued
    assert reg.describe() == "closed=10 b=-1 s=-1 stick"
    y = np.zeros(3)
    assert switch(reg, 1, 0.0, y, _fp(), 2, 0, slice(1, 3), 0.0)[0].kind == "touch_down"
    with pytest.raises(ValueError, match="no law is registered"):
        switch(reg, 2, 0.0, y, _fp(), 2, 0, slice(1, 3), 0.0)


def test_a_regime_round_trips_through_pickle_with_its_law():
    reg = initial_regime(np.ones(3), _fp(t0=100.0), True, "table")
    reg.switch_times = [0.5]
    back = pickle.loads(pickle.dumps(reg))
    assert back.law == "table" and back.set_valued and back.branch == 1
    assert back.describe() == reg.describe() == "closed=111 slip+"
    assert back.switch_times == [0.5] and np.array_equal(back.closed, reg.closed)


@pytest.mark.parametrize(("set_valued", "branch", "law", "text", "first"), [
    (True, 0, "coulomb", "closed=11 stick", "slip"),
    (False, 1, "feldmann", "closed=11 b=+1 s=-1 stick", "friction_branch")])
def test_a_regime_pickled_with_set_valued_gets_a_law_of_that_kind(set_valued, branch, law,
                                                                   text, first):
    # the state of a regime pickled before it carried its law (an older checkpoint)
    old = Regime.__new__(Regime)
    old.__dict__.update(closed=np.ones(2, dtype=np.int64), branch=branch, latch=-1,
                        v_ext=0.0, stick=True, dwell_end=NO_DWELL, set_valued=set_valued,
                        switch_times=[])
    back = pickle.loads(pickle.dumps(old))
    assert back.law == law and back.set_valued is set_valued and "set_valued" not in vars(back)
    assert back.describe() == text
    # and it switches as its kind does at friction root 0 (stick: break-away, else the branch)
    out = switch(back, 2, 0.0, np.array([0.0, 1.0, 1.0]), _fp(), 2, 0, slice(1, 3), 0.0)
    assert [tr.kind for tr in out] == [first]


def test_each_law_writes_its_regime_in_the_logs_notation():
    """docs/events.md: ``closed=1111011111 b=+1 s=-1 slip`` (Feldmann; LuGre the same form)
    and ``closed=111 slip+`` (the set-valued laws)."""
    closed = np.array([1, 1, 0], dtype=np.int64)
    assert Regime(closed=closed, law="feldmann", branch=1, latch=-1, stick=False
                  ).describe() == "closed=110 b=+1 s=-1 slip"
    assert Regime(closed=closed, law="lugre", branch=-1, latch=-1, stick=True
                  ).describe() == "closed=110 b=-1 s=-1 stick"
    for law in ("coulomb", "table"):
        assert [Regime(closed=closed, law=law, branch=b).describe() for b in (0, 1, -1)] == [
            "closed=110 stick", "closed=110 slip+", "closed=110 slip-"]
    assert Regime(closed=closed).describe() == "closed=110 b=-1 s=-1 stick"  # no friction
    with pytest.raises(ValueError, match="no law is registered"):
        Regime(closed=closed, law="amontons").describe()
