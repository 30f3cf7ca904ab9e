"""Assemble a scene into a :class:`.System`: flat kernel arrays, regimes, consistent states.

``assemble(scene)`` runs the preprocessing once (roughness profile, contact points, the
structure's modes at the contacts and their residual compliance, T0 calibration) and packs
everything the numba kernels need. The structure is a component
(:mod:`roughvib.physics.structures`, chosen by ``plate.kind``); its shapes are mass-normalised,
so the kernels' modal mass ``fp[FP_MMODAL]`` is 1 kg for every structure.
The ``System`` also knows the model's algebra that the event-driven solver needs between
smooth segments: static equilibrium (the initial state), the consistent algebraic forces and
derivatives after a regime switch, and the stored energy for the energy audit.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model.jacobian import jacobian_pattern
from roughvib.model.layout import ENERGY_TERMS, StateLayout
from roughvib.model.regimes import Regime
from roughvib.physics.friction import LAWS, FrictionLaw, calibrated_force_amplitude
from roughvib.physics.friction.feldmann import effective_latch_velocity
from roughvib.physics.structures import Structure, build_structure
from roughvib.physics.surface.contact import (
    ContactLayout,
    SceneInput,
    contact_layout,
    scene_input,
)
from roughvib.physics.surface.interp import cached_coefficients
from roughvib.physics.surface.roughness import Profile
from roughvib.scene import (
    Block,
    ModelValidityWarning,
    Scene,
    SceneError,
    user_stacklevel,
    validity_warnings,
)

# Regime is re-exported from .regimes
__all__ = ["GRAVITY", "MAX_RMS_SLOPE", "MAX_RMS_TO_BLOCK", "Regime", "System", "WARN_RMS_SLOPE",
           "WARN_RMS_TO_BLOCK", "assemble", "check_profile", "estimate_travel"]

GRAVITY = 9.81  # m/s^2, the paper's value (F_stat = m g)
#: how the run's summary names the tangential model a law is calibrated in
_CALIBRATION_MODELS = {"feldmann": "tangential model (F_N = m g)",
                       "set-valued": "set-valued tangential model (F_N = m g)",
                       "dynamic": "the law's own tangential model (F_N = m g)"}


@dataclass
class System:
    """A scene turned into arrays and algebra for the solvers (see module docstring)."""

    scene: Scene
    layout: StateLayout
    profile: Profile
    contact_s: np.ndarray          # (K,) profile coordinates of the contacts at x = 0 [m]
    contact_xy: np.ndarray         # (K, 2) plate coordinates of the contacts [m]
    structure: Structure           # the structure component (plate.kind)
    force_amplitude: float         # T0 [N] (calibrated or given)
    calibration: dict
    off: np.ndarray
    fp: np.ndarray
    omega2: np.ndarray
    cdamp: np.ndarray
    phi: np.ndarray
    phi_obs: np.ndarray
    stiff: np.ndarray
    cres: np.ndarray
    prof: np.ndarray
    #: (K,) coordinates of the contacts at x = 0 in the interpolant's cells (``prof``): the
    #: interpolant holds one window of the input per contact (:func:`input_windows`)
    input_s: np.ndarray
    #: (K, 2) tangential displacements x [m] between which contact k stays in its window
    input_reach: np.ndarray
    work: np.ndarray = field(repr=False)
    warnings: list[str] = field(default_factory=list)  # validity warnings (one line each)
    #: how the contact was resolved: points, stiffness, their sources, selection, r1
    contact: dict = field(default_factory=dict)
    #: (R,) largest absolute shape value of each mode over the structure [1/sqrt(kg)]: the
    #: displacement per unit modal coordinate, which scales the modes' absolute tolerances
    mode_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: (R, K) x-slopes of the shapes at the contacts (area means for contact.patch = "area")
    #: [1/(m sqrt(kg))]; with contact.friction_moment the kernels read them, times the lever
    #: plate.thickness / 2, from ``fp`` (``off[OFF_IPSI]``, roughvib.model.layout)
    phi_dx: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), repr=False)

    # ---- sizes -----------------------------------------------------------------------
    @property
    def n_contacts(self) -> int:
        return int(self.off[kn.OFF_K])

    @property
    def n_modes(self) -> int:
        return int(self.off[kn.OFF_R])

    @property
    def tangential(self) -> bool:
        return self.layout.tangential

    def kernel_args(self, reg: np.ndarray, rf: np.ndarray) -> tuple:
        """The shared argument tail of the residual/Jacobian/output kernels."""
        return (self.off, self.fp, self.omega2, self.cdamp, self.phi, self.phi_obs, self.stiff,
                self.cres, self.input_s, self.prof, reg, rf, self.work)

    def event_args(self, reg: np.ndarray, rf: np.ndarray) -> tuple:
        return (self.off, self.fp, self.phi, self.cres, self.input_s, self.prof, reg, rf,
                self.work)

    def jacobian_pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """Row and column indices of IDA's Jacobian entries (the pattern pass of
        :func:`roughvib.model.jacobian.jacobian_entries` on this system's arrays).

        Returns
        -------
        rows, cols : ndarray (nnz,) of int64
            In the order of :func:`roughvib.model.jacobian.jacobian_values`.
        """
        return jacobian_pattern(*self.kernel_args(*self.new_regime_arrays()))

    def new_regime_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Zeroed regime arrays ``(reg, rf)`` of the kernels' argument tail (int64, float64)."""
        return np.zeros(kn.REG_CLOSED + self.n_contacts, dtype=np.int64), np.zeros(2)

    @property
    def set_valued(self) -> bool:
        """Whether the friction force is an algebraic state (a set-valued law)."""
        return self.layout.friction_state

    # ---- algebra ---------------------------------------------------------------------
    def static_compliance_matrix(self) -> np.ndarray:
        """G = Phi^T diag(1/(M w^2)) Phi + C_res: static plate compliance at the contacts [m/N].

        With no mode kept (a modal plate whose first mode lies above ``plate.max_frequency``)
        G is C_res alone: the whole static compliance, or zero without residual compliance
        and for a rigid plate.
        """
        if self.n_modes == 0:
            return self.cres.copy()
        inv = 1.0 / (self.fp[kn.FP_MMODAL] * self.omega2)
        return (self.phi * inv[:, None]).T @ self.phi + self.cres

    def contact_forces(self, t: float, y: np.ndarray, closed: np.ndarray) -> np.ndarray:
        """Algebraic contact forces consistent with the differential states and a contact set.

        Solves ``(diag(1/s) + C_res) F = z - Phi^T q + h`` on the closed contacts, F = 0 on the
        open ones.
        """
        k_all = self.n_contacts
        iF = self.layout.slice("contact.force")
        yy = y.copy()
        yy[iF] = 0.0
        kn.compressions(t, yy, self.off, self.fp, self.phi, self.cres, self.input_s,
                        self.prof, self.work)
        rhs = self.work[:k_all].copy()  # compression with F = 0 in the residual term
        return self._solve_closed(closed, rhs)

    def _solve_closed(self, closed: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """x with (diag(1/s) + C_res) x = rhs on the closed contacts, 0 on the open ones."""
        x = np.zeros(self.n_contacts)
        idx = np.flatnonzero(closed)
        if idx.size:
            A = self.cres[np.ix_(idx, idx)] + np.diag(1.0 / self.stiff[idx])
            x[idx] = np.linalg.solve(A, rhs[idx])
        return x

    def force_rates(self, t: float, y: np.ndarray, closed: np.ndarray) -> np.ndarray:
        """Time derivatives of the contact forces [N/s] that keep the contact law.

        On the closed contacts F = s (z - w + h(s_k + x)) with w = phi^T q + C_res F, so
        ``(diag(1/s) + C_res) dF/dt = z' - phi^T q' + h'(s_k + x) x'``; 0 on the open ones.
        """
        k_all = self.n_contacts
        lay = self.layout
        kn.compressions(t, y, self.off, self.fp, self.phi, self.cres, self.input_s,
                        self.prof, self.work)
        _, vx = kn.tangential_kinematics(t, y, self.off, self.fp)
        rate = y[lay.index("block.vz")] + self.work[k_all:2 * k_all] * vx
        if self.n_modes:
            rate = rate - self.phi.T @ y[lay.slice("plate.dq")]
        return self._solve_closed(closed, rate)

    def consistent(self, t: float, y: np.ndarray, reg: np.ndarray, rf: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Consistent (y, yp) for the regime in ``reg``: algebraic forces, then yp = f(y).

        In the Coulomb stick regime the tangential velocity is set to exactly zero first.
        The contact forces' yp are their rates (:meth:`force_rates`): IDA's first step after a
        restart predicts the forces from them, and a zero rate at a touch-down failed its
        error test down to the minimum step at tight tolerances (atol <= 1e-16 m).
        """
        y = np.array(y, dtype=float)
        y[self.layout.slice("contact.force")] = self.contact_forces(
            t, y, reg[kn.REG_CLOSED:])
        if self.set_valued:
            if reg[kn.REG_B] == 0:
                y[self.layout.index("block.vx")] = 0.0
            y[self.layout.index("friction.force")] = kn.set_valued_friction(t, y, self.off,
                                                                          self.fp, reg)
        res = np.empty_like(y)
        kn.residual(t, y, np.zeros_like(y), res, *self.kernel_args(reg, rf))
        yp = -res
        yp[self.layout.algebraic_indices] = 0.0
        yp[self.layout.slice("contact.force")] = self.force_rates(t, y, reg[kn.REG_CLOSED:])
        return y, yp

    def static_equilibrium(self, x0: float = 0.0, max_iter: int = 200
                           ) -> tuple[np.ndarray, np.ndarray]:
        """Static equilibrium of block and plate under gravity at tangential position x0.

        Active-set iteration on the unilateral springs: solve with the current closed set,
        open springs in tension, close springs that penetrate, repeat.

        Returns
        -------
        y : ndarray
            State with static z, q, F (velocities and energy integrals zero).
        closed : ndarray of int, shape (K,)
        """
        K = self.n_contacts
        lay = self.layout
        m = self.fp[kn.FP_MASS]
        W = m * self.fp[kn.FP_GRAV]
        y = np.zeros(lay.size)
        if lay.tangential:
            y[lay.index("block.x")] = x0
        tt = 0.0
        heights = np.empty(K)
        for k in range(K):
            heights[k] = _profile_height(self, self.input_s[k] + x0)
        G = self.static_compliance_matrix()
        # start with the highest contact only closed (always a feasible first guess)
        closed = np.zeros(K, dtype=np.int64)
        closed[int(np.argmax(heights))] = 1
        for _ in range(max_iter):
            idx = np.flatnonzero(closed)
            n = idx.size
            # unknowns: F_idx, z ; rows: F/s + G F - z = h (closed), sum F = W
            A = np.zeros((n + 1, n + 1))
            A[:n, :n] = G[np.ix_(idx, idx)] + np.diag(1.0 / self.stiff[idx])
            A[:n, n] = -1.0
            A[n, :n] = 1.0
            b = np.concatenate([heights[idx], [W]])
            sol = np.linalg.solve(A, b)
            F = np.zeros(K)
            F[idx] = sol[:n]
            z = sol[n]
            comp = z - G @ F + heights
            new = closed.copy()
            new[(closed == 1) & (F < 0)] = 0
            new[(closed == 0) & (comp > 0)] = 1
            if np.array_equal(new, closed):
                break
            if not new.any():
                new[int(np.argmax(comp))] = 1
            closed = new
        else:  # pragma: no cover - the active set converges in <= K+1 iterations here
            raise RuntimeError("static equilibrium: contact active set did not converge")
        y[lay.index("block.z")] = z
        y[lay.slice("contact.force")] = F
        if self.n_modes:
            y[lay.slice("plate.q")] = (self.phi @ F) / (self.fp[kn.FP_MMODAL] * self.omega2)
        _ = tt
        return y, closed

    def stored_energy(self, y: np.ndarray) -> float:
        """Kinetic + elastic + gravitational energy of the state [J] (zero level z = 0)."""
        lay = self.layout
        m = self.fp[kn.FP_MASS]
        e = 0.5 * m * y[lay.index("block.vz")] ** 2
        e -= m * self.fp[kn.FP_GRAV] * y[lay.index("block.z")]
        if lay.tangential:
            e += 0.5 * m * y[lay.index("block.vx")] ** 2
        if self.n_modes:
            q = y[lay.slice("plate.q")]
            dq = y[lay.slice("plate.dq")]
            e += 0.5 * self.fp[kn.FP_MMODAL] * np.sum(dq**2 + self.omega2 * q**2)
        F = y[lay.slice("contact.force")]
        e += 0.5 * np.sum(F**2 / self.stiff) + 0.5 * F @ self.cres @ F
        return float(e)

    def energy_terms(self, y: np.ndarray) -> dict[str, float]:
        """The running energy integrals of a state [J], by name (ENERGY_TERMS)."""
        return {n: float(y[self.layout.index(f"energy.{n}")]) for n in ENERGY_TERMS}


def _profile_height(system: System, s: float) -> float:
    from roughvib.physics.surface.interp import profile_eval

    return profile_eval(system.prof, system.fp[kn.FP_S0], system.fp[kn.FP_DX], s)[0]


#: above this rms slope of the input profile the run is refused: the contact springs act
#: vertically and friction along the mean surface, which is the small-slope limit; at an rms
#: slope of 1 a typical flank is at 45 degrees and the model does not describe the contact
MAX_RMS_SLOPE = 1.0
#: above this rms slope a run warns: the neglected terms are of the order of the slope (10 %)
WARN_RMS_SLOPE = 0.1
#: above this fraction of the block's smaller side the rms roughness is refused: the block is
#: rigid, cannot pitch or roll, and rests on heights that are small against its size
MAX_RMS_TO_BLOCK = 1e-2
#: above this fraction a run warns (surface heights then approach waviness, not roughness)
WARN_RMS_TO_BLOCK = 1e-3


def _roughness_key(scene: Scene) -> str:
    r = scene.roughness
    if r.kind == "file":
        return f"roughness.path {r.path!r} (units = {r.units!r})"
    if r.kind == "sinusoid":
        return f"roughness.amplitude {r.amplitude} m (wavelength {r.wavelength} m)"
    if r.reduce_3d:
        return f"roughness.raw_rms {r.raw_rms} m"
    return f"roughness.rms {r.rms} m"


def check_profile(scene: Scene, profile: Profile) -> list[str]:
    """Plausibility of the input profile: refuse what the model cannot represent, warn where a
    legal profile lies outside the model's validity.

    Parameters
    ----------
    scene : Scene
    profile : Profile
        The input profile of the scene (``stats`` with ``rms`` [m] and ``rms_slope`` [-]).

    Returns
    -------
    list of str
        Warnings (one line each).

    Raises
    ------
    SceneError
        rms slope above :data:`MAX_RMS_SLOPE`, or rms height above :data:`MAX_RMS_TO_BLOCK`
        of the block's smaller side (a profile in micrometres declared as metres fails both).
    """
    rms = float(profile.stats.get("rms", 0.0))
    slope = float(profile.stats.get("rms_slope", 0.0))
    side = min(scene.block.length, scene.block.width)
    key = _roughness_key(scene)
    hint = "; are the file's heights in um or nm?" if scene.roughness.kind == "file" else ""
    if slope > MAX_RMS_SLOPE:
        raise SceneError(f"{key} gives an input profile with rms slope {slope:.3g}, the model "
                         f"needs at most {MAX_RMS_SLOPE:g} (vertical contact springs and "
                         f"friction along the mean surface hold for small slopes only){hint}")
    if rms > MAX_RMS_TO_BLOCK * side:
        raise SceneError(f"{key} gives an input profile of {rms:.3g} m rms, the model needs at "
                         f"most {MAX_RMS_TO_BLOCK:g} x the block's smaller side ({side} m) (a "
                         f"rigid block that cannot pitch or roll, on heights small against "
                         f"its size){hint}")
    out = []
    if slope > WARN_RMS_SLOPE:
        out.append(f"{key} gives an input profile with rms slope {slope:.3g}, above "
                   f"{WARN_RMS_SLOPE:g}: the small-slope contact model neglects terms of the "
                   f"order of the slope")
    if rms > WARN_RMS_TO_BLOCK * side:
        out.append(f"{key} gives an input profile of {rms:.3g} m rms, above "
                   f"{WARN_RMS_TO_BLOCK:g} x the block's smaller side ({side} m): heights "
                   f"approach waviness, which a rigid block without pitch and roll does not "
                   f"follow")
    return out


def estimate_travel(scene: Scene) -> float:
    """Tangential travel of the contacts beyond their rest positions [m], estimated before
    the run (for a calibrated force: 1.5 x the sinusoidal displacement amplitude of the target
    velocity)."""
    exc = scene.excitation
    if exc.kind == "prescribed":
        return abs(exc.velocity) * scene.output.duration + exc.amplitude
    if exc.target_rms_velocity is not None and exc.frequency > 0:
        return 2.0 * math.sqrt(2.0) * exc.target_rms_velocity / exc.omega * 1.5
    return 0.0


def _window_travel(scene: Scene, force_amplitude: float) -> float:
    """How far either way the input windows reach [m] (:func:`input_windows`): the prescribed
    travel, or for a force-driven block the peak-to-peak travel of the frictionless block
    from rest, 2 T0 / (m omega^2), which friction and damping only shorten. It depends on T0
    alone, not on how T0 was found, so the saved scene (with the calibrated T0) builds the
    same windows as the run that calibrated it; a run that still leaves its windows ends with
    an error (:func:`check_stroke`)."""
    exc = scene.excitation
    if exc.kind == "prescribed":
        return abs(exc.velocity) * scene.output.duration + abs(exc.amplitude)
    if exc.omega > 0:
        return 2.0 * abs(force_amplitude) / (scene.block.mass * exc.omega**2)
    return 0.0


def _check_travel(scene: Scene, profile: Profile, contact_s: np.ndarray, travel: float) -> None:
    lo = profile.s0
    hi = profile.s0 + (profile.z.size - 1) * profile.dx
    if contact_s.min() - travel < lo or contact_s.max() + travel > hi:
        r = scene.roughness
        if r.kind == "file":
            raise SceneError(f"roughness.path {r.path!r} must cover the contacts' travel of "
                             f"about ±{travel:.3g} m beyond the block window, got a profile of "
                             f"{hi - lo:.6g} m")
        raise SceneError(
            f"roughness.trace_length must cover the contacts' travel of about ±{travel:.3g} m "
            f"beyond the block window, got {r.trace_length} m")


def _checked_contacts(scene: Scene, travel: float | None, warn: bool
                      ) -> tuple[SceneInput, ContactLayout, list[str]]:
    """The scene's input profile and contact points, checked before any expensive step.

    Parameters
    ----------
    scene : Scene
    travel : float or None
        Tangential travel of the contacts the profile must cover [m] (not checked if None).
    warn : bool
        Issue the validity notes as :class:`~roughvib.scene.ModelValidityWarning`.

    Returns
    -------
    inp : SceneInput
        The kinematic input (``inp.profile``) and its statistical contact.
    layout : ContactLayout
        The contact points [m] and the total contact stiffness [N/m]
        (:func:`~roughvib.physics.surface.contact.contact_layout`).
    notes : list of str
        The profile's plausibility notes (:func:`check_profile`), the scene's validity
        warnings and the contact filter's note, one line each.

    Raises
    ------
    SceneError
        An implausible profile (:func:`check_profile`), or one that does not cover
        ``travel``.
    """
    inp = scene_input(scene)
    profile = inp.profile
    notes = check_profile(scene, profile) + validity_warnings(scene)
    if profile.stats.get("contact_filter_note"):
        notes.append(profile.stats["contact_filter_note"])
    # contact points and s_total, as given or from the statistical contact (docs/theory.md);
    # a measured profile brings its own spectrum, synthetic ones use the model PSD
    cl = contact_layout(scene, profile, inp.statistical)
    if travel is not None:
        _check_travel(scene, profile, cl.positions, travel)
    for note in notes if warn else ():
        warnings.warn(note, ModelValidityWarning, stacklevel=user_stacklevel())
    return inp, cl, notes


def _vertical_damping(block: Block, s_total: float) -> float:
    """The block's vertical damper r1 [N s/m]: ``block.vertical_damping`` as given, or for
    ``"auto"`` ``2 zeta sqrt(s_total m)``, zeta = ``block.vertical_damping_ratio``, of the
    total contact stiffness ``s_total`` [N/m] and the block's mass m [kg]."""
    if isinstance(block.vertical_damping, str):
        return 2.0 * block.vertical_damping_ratio * math.sqrt(s_total * block.mass)
    return float(block.vertical_damping)


def _structure_at_contacts(scene: Scene, structure: Structure, contact_xy: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The structure's mode shapes, their x-slopes and its residual compliance at the
    contacts (point values, or area means for ``contact.patch = "area"``), and its shapes at
    the observation point.

    Parameters
    ----------
    scene : Scene
    structure : Structure
        Mass-normalised shapes [1/sqrt(kg)].
    contact_xy : ndarray, shape (K, 2)
        Plate coordinates of the contacts [m].

    Returns
    -------
    phi : ndarray, shape (R, K)
        Shapes at the contacts [1/sqrt(kg)], C-contiguous.
    phi_dx : ndarray, shape (R, K)
        Their x-slopes [1/(m sqrt(kg))].
    cres : ndarray, shape (K, K)
        Residual compliance [m/N] (symmetric; zero without ``plate.residual_compliance``).
    phi_obs : ndarray, shape (R,)
        Shapes at ``plate.observation_position`` [1/sqrt(kg)].
    """
    blk, plt = scene.block, scene.plate
    K = contact_xy.shape[0]
    x0, y0 = plt.block_position
    obs = np.array([plt.observation_position])
    if scene.contact.patch == "area":
        # every contact force spread evenly over the block's nominal contact area, which stays
        # centred at plate.block_position (the contacts hold their plate points)
        patch = ((x0, y0), (blk.length, blk.width))
        psi = structure.patch_shapes(*patch)
        phi = np.repeat(psi[:, None], K, axis=1)
        phi_dx = np.repeat(structure.patch_slopes(*patch)[:, None], K, axis=1)
        c = structure.patch_residual_compliance(*patch) if plt.residual_compliance else None
        cres = np.full((K, K), 0.0 if c is None else c)
    else:
        phi = structure.shapes(contact_xy)
        phi_dx = structure.slopes(contact_xy)
        c = structure.residual_compliance(contact_xy) if plt.residual_compliance else None
        cres = np.zeros((K, K)) if c is None else 0.5 * (c + c.T)
    phi = np.ascontiguousarray(phi, dtype=float)
    phi_obs = np.ascontiguousarray(structure.shapes(obs)[:, 0], dtype=float)
    return phi, phi_dx, cres, phi_obs


def _force_amplitude(scene: Scene, law: FrictionLaw, table: np.ndarray,
                     force_amplitude: float | None) -> tuple[float, dict]:
    """The excitation force amplitude T0 [N] and how it was found.

    Parameters
    ----------
    scene : Scene
    law : FrictionLaw
        The scene's friction law (``LAWS[friction.law]``).
    table : ndarray
        The law's packed parameters (:attr:`FrictionLaw.pack`).
    force_amplitude : float or None
        A T0 given to :func:`assemble` [N]; it wins over the scene's.

    Returns
    -------
    T0 : float
        [N]; 0 under prescribed motion.
    calibration : dict
        ``method`` (``given``, ``scene`` or the calibration's tangential model) and, when
        calibrated, ``target_rms_velocity`` [m/s] and ``cache``; empty under prescribed
        motion.

    Raises
    ------
    SceneError
        The calibration cannot reach ``excitation.target_rms_velocity``.
    """
    blk, exc, fr = scene.block, scene.excitation, scene.friction
    if exc.kind != "force":
        return 0.0, {}
    if force_amplitude is not None:
        return float(force_amplitude), {"method": "given"}
    if exc.force_amplitude is not None:
        return float(exc.force_amplitude), {"method": "scene"}
    try:
        T0, cache = calibrated_force_amplitude(
            exc.target_rms_velocity, blk.mass, blk.tangential_damping, blk.mass * GRAVITY,
            exc.omega, fr, table)
    except (RuntimeError, ValueError) as err:
        raise SceneError(
            f"excitation.target_rms_velocity cannot be reached by calibrating T0 with this "
            f"friction law ({err}); check the friction keys or give "
            f"excitation.force_amplitude [N], got {exc.target_rms_velocity} m/s") from None
    return T0, {"method": _CALIBRATION_MODELS[law.calibration],
                "target_rms_velocity": exc.target_rms_velocity, "cache": cache}


def assemble(scene: Scene, *, force_amplitude: float | None = None,
             travel: float | None = None, warn: bool = True) -> System:
    """Turn a validated scene into a :class:`System` (preprocessing happens here, once).

    Every check of the input runs before the expensive steps (plate modes, residual
    compliance, T0 calibration): the profile's plausibility (:func:`check_profile`), the
    validity warnings (issued as :class:`~roughvib.scene.ModelValidityWarning` and kept in
    ``System.warnings``) and, with ``travel``, the coverage of the profile.

    The system's ``scene`` carries the resolved solver section (``Scene.resolved_solver``:
    a concrete method, tolerances and step from the accuracy preset unless given), which is
    what the solvers read.

    Parameters
    ----------
    scene : Scene
    force_amplitude : float, optional
        Use this T0 [N] instead of the scene's value or calibration.
    travel : float, optional
        Check that the profile covers this tangential travel of the contacts [m] (see
        :func:`estimate_travel`).
    warn : bool
        Issue the validity warnings (they are in ``System.warnings`` either way); off for a
        second assembly of a scene whose warnings were already issued.
    """
    scene = replace(scene, solver=scene.resolved_solver())
    blk, plt, exc, fr = scene.block, scene.plate, scene.excitation, scene.friction
    tangential = exc.kind == "force"

    inp, cl, notes = _checked_contacts(scene, travel, warn)
    profile = inp.profile
    spos, s_total, K = cl.positions, cl.stiffness_total, cl.n
    stiff = np.full(K, s_total / K)
    r1 = _vertical_damping(blk, s_total)
    x0, y0 = plt.block_position
    contact_xy = np.column_stack([x0 + (spos - profile.s_centre), np.full(K, y0)])

    structure = build_structure(plt, scene.base_dir)
    for note in structure.notes:  # e.g. imported modes that give no residual compliance
        notes.append(note)
        if warn:
            warnings.warn(note, ModelValidityWarning, stacklevel=user_stacklevel())
    phi, phi_dx, cres, phi_obs = _structure_at_contacts(scene, structure, contact_xy)
    omega2 = structure.omega**2
    cdamp = 2.0 * structure.damping_ratio * structure.omega
    R = phi.shape[0]
    law = LAWS[fr.law]
    layout = StateLayout(R, K, tangential, friction_state=tangential and law.set_valued,
                         law_states=law.states if tangential else 0)
    # the law's packed parameters (a tabulated curve, read and checked before the
    # calibration needs it; a dynamic law's constants)
    table = law.pack(fr, scene.base_dir) if tangential else np.zeros(0)

    T0, calibration = _force_amplitude(scene, law, table, force_amplitude)
    stiff_info = cl.statistical.as_dict() if cl.statistical is not None else {}
    if stiff_info:
        calibration["contact_stiffness"] = stiff_info

    coeffs, input_s, input_reach = input_windows(profile, spos, _window_travel(scene, T0),
                                                 scene.roughness.interpolation)
    fp = np.zeros(kn.N_FP)
    fp[kn.FP_MASS] = blk.mass
    fp[kn.FP_GRAV] = GRAVITY
    fp[kn.FP_R1] = r1
    fp[kn.FP_R2] = blk.tangential_damping
    fp[kn.FP_T0] = T0
    fp[kn.FP_OMEGA] = exc.omega
    fp[kn.FP_MU_SLIP] = fr.mu_slip
    fp[kn.FP_MU_STICK] = fr.mu_stick
    par = fr.parameters  # the law's own keys, in their slots (0 where it has none)
    for key, slot in kn.FP_LAW_KEYS.items():
        fp[slot] = par.get(key) or 0.0
    fp[kn.FP_EPS] = effective_latch_velocity(par)
    fp[kn.FP_VSTICK] = fr.stick_velocity
    fp[kn.FP_PV] = exc.velocity if not tangential else 0.0
    fp[kn.FP_PA] = exc.amplitude if not tangential else 0.0
    fp[kn.FP_PW] = exc.omega
    fp[kn.FP_MMODAL] = 1.0  # mass-normalised shapes (physics/structures)
    fp[kn.FP_S0] = 0.0  # the windows' own coordinate (input_windows)
    fp[kn.FP_DX] = profile.dx
    fp = np.concatenate([fp, table])  # the law's own parameters follow the scalars (N_FP on)
    off = layout.offsets(law.law_id)
    if scene.contact.friction_moment and tangential and R > 0:
        # the friction force acts on the top surface, hp/2 above the mid-plane: its lever
        # times the x-slopes of the shapes, contact-major, after the table (kernels.moment_*)
        off[kn.OFF_IPSI] = fp.size
        psi = 0.5 * plt.thickness * np.asarray(phi_dx, dtype=float)
        fp = np.concatenate([fp, np.ascontiguousarray(psi.T).ravel()])

    return System(
        scene=scene, layout=layout, profile=profile, contact_s=spos, contact_xy=contact_xy,
        structure=structure, force_amplitude=T0, calibration=calibration,
        off=off, fp=fp,
        omega2=np.ascontiguousarray(omega2), cdamp=np.ascontiguousarray(cdamp), phi=phi,
        phi_obs=phi_obs, stiff=stiff, cres=np.ascontiguousarray(cres), prof=coeffs,
        input_s=input_s, input_reach=input_reach,
        work=np.zeros(kn.work_size(K)), warnings=notes,
        contact={**cl.as_dict(), "vertical_damping": r1, "input": inp.band.as_dict()},
        mode_scale=np.asarray(structure.max_shape(), dtype=float),
        phi_dx=np.ascontiguousarray(phi_dx, dtype=float),
    )


#: cells of a window beyond the travel it must cover: a spline's end conditions disturb
#: only the few cells next to its ends
WINDOW_MARGIN_CELLS = 16


def input_windows(profile: Profile, contact_s: np.ndarray, travel: float, kind: str
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interpolant of the input around each contact, in one coefficient array.

    Contact k reads the profile only within ``contact_s[k] +- travel``; its window is that
    stretch of the profile's grid plus :data:`WINDOW_MARGIN_CELLS` cells on each side (taken
    across the period's end for a periodic field; clipped to a measured profile), and its own
    interpolant (:func:`~roughvib.physics.surface.interp.cached_coefficients`) is built on it.
    The windows follow each other on one grid of the profile's spacing, one spare cell
    apart, starting at 0: the kernels' profile coordinate of contact k at x = 0 is
    ``input_s[k]``. A fine grid thus costs memory only where the contacts go.

    Parameters
    ----------
    profile : Profile
    contact_s : ndarray, shape (K,)
        Profile coordinates of the contacts at x = 0 [m].
    travel : float
        Largest tangential travel either way [m], >= 0.
    kind : {"linear", "cubic", "quintic"}

    Returns
    -------
    coefficients : ndarray, shape (cells, degree + 1)
    input_s : ndarray, shape (K,)
        [m] in the windows' coordinate.
    reach : ndarray, shape (K, 2)
        The displacements x [m] between which contact k reads its own window.
    """
    dx = profile.dx
    n = profile.z.size
    half = int(math.ceil(travel / dx)) + WINDOW_MARGIN_CELLS
    blocks, input_s, reach = [], [], []
    start = 0
    for s_k in np.asarray(contact_s, dtype=float):
        pos = (s_k - profile.s0) / dx
        i0, i1 = int(math.floor(pos)) - half, int(math.ceil(pos)) + half
        if not profile.periodic:
            i0, i1 = max(i0, 0), min(i1, n - 1)
        idx = np.arange(i0, i1 + 1) % n
        c, _ = cached_coefficients(np.ascontiguousarray(profile.z[idx]), dx, kind)
        blocks.append(c)
        blocks.append(c[-1:])  # a spare cell: never read by a contact within its reach
        local = (pos - i0) * dx
        input_s.append(start * dx + local)
        reach.append((-local + WINDOW_MARGIN_CELLS * dx,
                      (i1 - i0) * dx - local - WINDOW_MARGIN_CELLS * dx))
        start += c.shape[0] + 1
    return (np.ascontiguousarray(np.vstack(blocks)), np.asarray(input_s, dtype=float),
            np.asarray(reach, dtype=float))


def check_stroke(system: System, x: np.ndarray) -> None:
    """Raise if the block's tangential travel left a contact's window of the input."""
    lo, hi = float(np.min(x)), float(np.max(x))
    if lo < system.input_reach[:, 0].max() or hi > system.input_reach[:, 1].min():
        raise SceneError(
            f"roughness.trace_length must cover the contacts' travel: the block moved over "
            f"[{lo:.4g}, {hi:.4g}] m but the input around the contacts covers only "
            f"[{system.input_reach[:, 0].max():.4g}, {system.input_reach[:, 1].min():.4g}] m "
            f"(estimated before the run), got {system.scene.roughness.trace_length} m")
