"""Assemble a scene into a :class:`System`: flat kernel arrays, regimes, consistent states.

``assemble(scene)`` runs the preprocessing once (roughness profile, contact points, plate
modes, residual compliance, T0 calibration) and packs everything the numba kernels need.
The ``System`` also knows the model's algebra that the event-driven solver needs between
smooth segments: static equilibrium (the initial state), the consistent algebraic forces and
derivatives after a regime switch, and the stored energy for the energy audit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roughvib.model import kernels as kn
from roughvib.model.layout import ENERGY_TERMS, StateLayout
from roughvib.model.regimes import Regime
from roughvib.physics.friction import calibrate_force_amplitude
from roughvib.physics.plate import PlateModes, mode_shapes, plate_modes, residual_compliance
from roughvib.physics.surface.contact import contact_layout
from roughvib.physics.surface.interp import build_coefficients
from roughvib.physics.surface.roughness import Profile, build_profile
from roughvib.scene import Scene, SceneError

__all__ = ["GRAVITY", "Regime", "System", "assemble"]  # Regime re-exported from .regimes

GRAVITY = 9.81  # m/s^2, the paper's value (F_stat = m g)


@dataclass
class System:
    """A scene turned into arrays and algebra for the solvers (see module docstring)."""

    scene: Scene
    layout: StateLayout
    profile: Profile
    contact_s: np.ndarray          # (K,) profile coordinates of the contacts at x = 0 [m]
    contact_xy: np.ndarray         # (K, 2) plate coordinates of the contacts [m]
    modes: PlateModes | None
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
    work: np.ndarray = field(repr=False)
    #: how the contact was resolved: points, stiffness, their sources, selection, r1
    contact: dict = field(default_factory=dict)

    # ---- sizes -----------------------------------------------------------------------
    @property
    def n_contacts(self) -> int:
        return int(self.off[9])

    @property
    def n_modes(self) -> int:
        return int(self.off[8])

    @property
    def tangential(self) -> bool:
        return self.layout.tangential

    def kernel_args(self, reg: np.ndarray, rf: np.ndarray) -> tuple:
        """The shared argument tail of the residual/Jacobian/output kernels."""
        return (self.off, self.fp, self.omega2, self.cdamp, self.phi, self.phi_obs, self.stiff,
                self.cres, self.contact_s, self.prof, reg, rf, self.work)

    def event_args(self, reg: np.ndarray, rf: np.ndarray) -> tuple:
        return (self.off, self.fp, self.phi, self.cres, self.contact_s, self.prof, reg, rf,
                self.work)

    def new_regime_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(kn.REG_CLOSED + self.n_contacts, dtype=np.int64), np.zeros(2)

    @property
    def coulomb(self) -> bool:
        """Whether the friction force is an algebraic state (set-valued Coulomb law)."""
        return self.layout.friction_state

    # ---- algebra ---------------------------------------------------------------------
    def static_compliance_matrix(self) -> np.ndarray:
        """G = Phi^T diag(1/(M w^2)) Phi + C_res: static plate compliance at the contacts [m/N]."""
        if self.n_modes == 0:
            return np.zeros((self.n_contacts, self.n_contacts))
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
        kn.compressions(t, yy, self.off, self.fp, self.phi, self.cres, self.contact_s,
                        self.prof, self.work)
        rhs = self.work[:k_all].copy()  # compression with F = 0 in the residual term
        F = np.zeros(k_all)
        idx = np.flatnonzero(closed)
        if idx.size:
            A = self.cres[np.ix_(idx, idx)] + np.diag(1.0 / self.stiff[idx])
            F[idx] = np.linalg.solve(A, rhs[idx])
        return F

    def consistent(self, t: float, y: np.ndarray, reg: np.ndarray, rf: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Consistent (y, yp) for the regime in ``reg``: algebraic forces, then yp = f(y).

        In the Coulomb stick regime the tangential velocity is set to exactly zero first.
        """
        y = np.array(y, dtype=float)
        y[self.layout.slice("contact.force")] = self.contact_forces(
            t, y, reg[kn.REG_CLOSED:])
        if self.coulomb:
            if reg[kn.REG_B] == 0:
                y[self.layout.index("block.vx")] = 0.0
            y[self.layout.index("friction.force")] = kn.coulomb_friction(t, y, self.off,
                                                                          self.fp, reg)
        res = np.empty_like(y)
        kn.residual(t, y, np.zeros_like(y), res, *self.kernel_args(reg, rf))
        yp = -res
        yp[self.layout.algebraic_indices] = 0.0
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
            heights[k] = _profile_height(self, self.contact_s[k] + x0)
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


def assemble(scene: Scene, *, force_amplitude: float | None = None) -> System:
    """Turn a validated scene into a :class:`System` (preprocessing happens here, once).

    Parameters
    ----------
    scene : Scene
    force_amplitude : float, optional
        Use this T0 [N] instead of the scene's value or calibration.
    """
    blk, plt, exc, fr = scene.block, scene.plate, scene.excitation, scene.friction
    tangential = exc.kind == "force"

    profile = build_profile(scene.roughness, blk, Path(scene.base_dir))
    # contact points and s_total, as given or from the statistical contact (docs/theory.md);
    # a measured profile brings its own moments, synthetic ones use the model PSD
    cl = contact_layout(scene, profile)
    spos, s_total, K = cl.positions, cl.stiffness_total, cl.n
    stiff_info = cl.statistical.as_dict() if cl.statistical is not None else {}
    stiff = np.full(K, s_total / K)
    r1 = (2.0 * blk.vertical_damping_ratio * math.sqrt(s_total * blk.mass)
          if isinstance(blk.vertical_damping, str) else float(blk.vertical_damping))
    x0, y0 = plt.block_position
    contact_xy = np.column_stack([x0 + (spos - profile.s_centre), np.full(K, y0)])

    if plt.kind == "modal":
        modes = plate_modes(plt)
        phi = np.ascontiguousarray(mode_shapes(modes, contact_xy[:, 0], contact_xy[:, 1]))
        phi_obs = np.ascontiguousarray(
            mode_shapes(modes, np.array([plt.observation_position[0]]),
                        np.array([plt.observation_position[1]]))[:, 0])
        omega2 = modes.omega**2
        cdamp = 2.0 * modes.damping_ratio * modes.omega
        mmodal = modes.modal_mass
        cres = (np.ascontiguousarray(residual_compliance(plt, modes, contact_xy))
                if plt.residual_compliance else np.zeros((K, K)))
        cres = 0.5 * (cres + cres.T)
    else:
        modes = None
        phi = np.zeros((0, K))
        phi_obs = np.zeros(0)
        omega2 = np.zeros(0)
        cdamp = np.zeros(0)
        mmodal = 1.0
        cres = np.zeros((K, K))
    R = phi.shape[0]
    layout = StateLayout(R, K, tangential, friction_state=tangential and fr.law == "coulomb")

    calibration: dict = {}
    if not tangential:
        T0 = 0.0
    elif force_amplitude is not None:
        T0 = float(force_amplitude)
        calibration = {"method": "given"}
    elif exc.force_amplitude is not None:
        T0 = float(exc.force_amplitude)
        calibration = {"method": "scene"}
    else:
        try:
            T0 = float(calibrate_force_amplitude(
                exc.target_rms_velocity, blk.mass, blk.tangential_damping, blk.mass * GRAVITY,
                exc.omega, fr))
        except (RuntimeError, ValueError) as err:
            raise SceneError(
                f"excitation.target_rms_velocity cannot be reached by calibrating T0 with this "
                f"friction law ({err}); check the friction keys or give "
                f"excitation.force_amplitude [N], got {exc.target_rms_velocity} m/s") from None
        calibration = {"method": "tangential model (F_N = m g)",
                       "target_rms_velocity": exc.target_rms_velocity}
    if stiff_info:
        calibration["contact_stiffness"] = stiff_info

    coeffs = build_coefficients(profile.z, profile.dx, scene.roughness.interpolation)
    fp = np.zeros(kn.N_FP)
    fp[kn.FP_MASS] = blk.mass
    fp[kn.FP_GRAV] = GRAVITY
    fp[kn.FP_R1] = r1
    fp[kn.FP_R2] = blk.tangential_damping
    fp[kn.FP_T0] = T0
    fp[kn.FP_OMEGA] = exc.omega
    fp[kn.FP_MU_SLIP] = fr.mu_slip
    fp[kn.FP_MU_STICK] = fr.mu_stick
    fp[kn.FP_A1] = fr.a1
    fp[kn.FP_A2] = fr.a2
    fp[kn.FP_VH] = fr.hysteresis_velocity
    fp[kn.FP_EPS] = fr.effective_latch_velocity
    fp[kn.FP_VSTICK] = fr.stick_velocity
    fp[kn.FP_PV] = exc.velocity if not tangential else 0.0
    fp[kn.FP_PA] = exc.amplitude if not tangential else 0.0
    fp[kn.FP_PW] = exc.omega
    fp[kn.FP_MMODAL] = mmodal
    fp[kn.FP_S0] = profile.s0
    fp[kn.FP_DX] = profile.dx
    fp[kn.FP_VSTRIB] = fr.stribeck_velocity or 0.0
    fp[kn.FP_HYST] = fr.switching_hysteresis

    return System(
        scene=scene, layout=layout, profile=profile, contact_s=spos, contact_xy=contact_xy,
        modes=modes, force_amplitude=T0, calibration=calibration, off=layout.offsets(), fp=fp,
        omega2=np.ascontiguousarray(omega2), cdamp=np.ascontiguousarray(cdamp), phi=phi,
        phi_obs=phi_obs, stiff=stiff, cres=np.ascontiguousarray(cres), prof=coeffs,
        work=np.zeros(5 * K + 8),
        contact={**cl.as_dict(), "vertical_damping": r1},
    )


def check_stroke(system: System, x: np.ndarray) -> None:
    """Raise if the block's tangential travel leaves the roughness profile."""
    prof = system.profile
    lo = prof.s0
    hi = prof.s0 + (prof.z.size - 1) * prof.dx
    smin = system.contact_s.min() + float(np.min(x))
    smax = system.contact_s.max() + float(np.max(x))
    if smin < lo or smax > hi:
        raise SceneError(
            f"roughness.trace_length must cover the contacts' travel: contacts reach "
            f"[{smin:.4g}, {smax:.4g}] m but the profile spans [{lo:.4g}, {hi:.4g}] m, got "
            f"{system.scene.roughness.trace_length} m")
    _ = math
