"""Scene sections of the mechanical system: the block, the plate, the contact and the roughness.

Frozen dataclasses in SI units, each validated in ``__post_init__`` with the helpers of
:mod:`.checks`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from roughvib.scene.checks import (
    MAX_CONTACTS,
    MAX_MODES,
    SceneError,
    _auto_or_positive,
    _boolean,
    _check_bounds,
    _choice,
    _fmt,
    _integer,
    _nonneg,
    _opt_positive,
    _pair,
    _positive,
    _range,
    _set,
)

#: relative slack of the plate's mode cut (``Plate.keeps_mode``)
MODE_CUT_SLACK = 1e-12


@dataclass(frozen=True)
class Block:
    """The sliding mass-block (rigid, one vertical and one tangential degree of freedom).

    Attributes
    ----------
    mass : float
        Block mass m [kg]. Paper: 0.221 or 0.543.
    length, width : float
        Block footprint along the sliding direction and across it [m] (0.04 x 0.04).
    vertical_damping : float or "auto"
        Viscous damper r1 on the absolute vertical block velocity [N s/m] (docs/theory.md).
        ``"auto"`` (default): r1 = 2 zeta sqrt(s_total m), the damping ratio
        ``vertical_damping_ratio`` at the rigid-plate contact resonance of the stiffness
        actually used. The paper's hand-set value is 83 N s/m (scene ``paper-handset``).
    tangential_damping : float
        Viscous damper r2 on the absolute tangential block velocity [N s/m].
    vertical_damping_ratio : float
        zeta of ``vertical_damping = "auto"`` [-].
    """

    mass: float = 0.221
    length: float = 0.04
    width: float = 0.04
    vertical_damping: float | str = "auto"
    tangential_damping: float = 0.5
    vertical_damping_ratio: float = 0.05

    def __post_init__(self) -> None:
        _set(self, "mass", _positive("block.mass", self.mass, "kg"))
        _set(self, "length", _positive("block.length", self.length, "m"))
        _set(self, "width", _positive("block.width", self.width, "m"))
        if isinstance(self.vertical_damping, str):
            _choice("block.vertical_damping", self.vertical_damping, ("auto",))
        else:
            _set(self, "vertical_damping",
                 _nonneg("block.vertical_damping", self.vertical_damping, "N s/m"))
        _set(self, "tangential_damping",
             _nonneg("block.tangential_damping", self.tangential_damping, "N s/m"))
        _set(self, "vertical_damping_ratio",
             _range("block.vertical_damping_ratio", self.vertical_damping_ratio, 0.0, 1.0, "",
                    hi_open=True))
        _check_bounds(self, "block")


@dataclass(frozen=True)
class Plate:
    """The structure under the block: a simply supported Kirchhoff plate (``kind="modal"``),
    an immovable base (``"rigid"``) or modes read from a file (``"imported"``).

    Attributes
    ----------
    kind : {"modal", "rigid", "imported"}
        Which structure component (``roughvib.physics.structures``): ``modal`` the simply
        supported plate of the fields below; ``rigid`` drops all plate states; ``imported``
        reads mass-normalised modes from ``modes_file`` (docs/structures.md), for which the
        material fields are not used and ``loss_factor`` gives the damping of modes the file
        gives none for.
    length, width, thickness : float
        a, b, h [m]. Sliding is along the plate length (x).
    youngs_modulus : float
        E [Pa].
    poisson_ratio : float
        nu [-], in [0, 0.5).
    density : float
        rho [kg/m^3].
    loss_factor : float
        delta_p [-]; modal damping ratio zeta = loss_factor / 2.
    max_frequency : float
        All modes with f <= max_frequency are kept [Hz].
    block_position : tuple of float
        Plate coordinates (x0, y0) of the block centre [m].
    observation_position : tuple of float
        Plate coordinates of the plate accelerometer [m]; keep it away from the contacts.
    residual_compliance : bool
        Add the static compliance of the truncated modes at the contacts (docs/theory.md).
        ``imported``: the static compliance of the file's modes above ``max_frequency``
        (none if the file holds none).
    modes_file : str
        ``imported``: the modes file (``.npz``, or ``.unv``/``.uff`` universal file with
        datasets 2411 and 55), relative to the scene file's folder (docs/structures.md).
    """

    kind: str = "modal"
    length: float = 0.30
    width: float = 0.26
    thickness: float = 0.003
    youngs_modulus: float = 2.1e11
    poisson_ratio: float = 0.3
    density: float = 7850.0
    loss_factor: float = 0.003
    max_frequency: float = 50e3
    block_position: tuple[float, float] = (0.12, 0.11)
    observation_position: tuple[float, float] = (0.20, 0.08)
    residual_compliance: bool = True
    modes_file: str = ""

    def __post_init__(self) -> None:
        _set(self, "kind", _choice("plate.kind", self.kind, ("modal", "rigid", "imported")))
        if not isinstance(self.modes_file, str):
            raise SceneError(f"plate.modes_file must be a string (file path), got "
                             f"{_fmt(self.modes_file)}")
        if self.kind == "imported" and not self.modes_file:
            raise SceneError("plate.modes_file must name a modes file (.npz, .unv, .uff) when "
                             "plate.kind = 'imported', got ''")
        _set(self, "length", _positive("plate.length", self.length, "m"))
        _set(self, "width", _positive("plate.width", self.width, "m"))
        _set(self, "thickness", _positive("plate.thickness", self.thickness, "m"))
        _set(self, "youngs_modulus", _positive("plate.youngs_modulus", self.youngs_modulus, "Pa"))
        _set(self, "poisson_ratio",
             _range("plate.poisson_ratio", self.poisson_ratio, 0.0, 0.5, "", hi_open=True))
        _set(self, "density", _positive("plate.density", self.density, "kg/m^3"))
        _set(self, "loss_factor", _range("plate.loss_factor", self.loss_factor, 0.0, 2.0, ""))
        _set(self, "max_frequency", _positive("plate.max_frequency", self.max_frequency, "Hz"))
        _set(self, "residual_compliance",
             _boolean("plate.residual_compliance", self.residual_compliance))
        _check_bounds(self, "plate")
        for name in ("block_position", "observation_position"):
            x, y = _pair(f"plate.{name}", getattr(self, name), "m")
            if not (0.0 < x < self.length):
                raise SceneError(f"plate.{name}[0] must be inside (0, plate.length="
                                 f"{self.length}) m, got {x}")
            if not (0.0 < y < self.width):
                raise SceneError(f"plate.{name}[1] must be inside (0, plate.width="
                                 f"{self.width}) m, got {y}")
            _set(self, name, (x, y))
        if self.kind == "modal":
            # the number of modes is bounded to keep a typo (1e9 Hz) from exhausting memory;
            # the estimate derives from six keys, so check it is a finite number and name them
            # all (the bounds keep it finite; this guards whatever they miss)
            n_est = math.nan
            try:
                b = self.youngs_modulus * self.thickness**3 / (12 * (1 - self.poisson_ratio**2))
                c = math.sqrt(b / (self.density * self.thickness))  # sqrt(B'/m'') [m^2/s]
                n_est = self.length * self.width * (2 * math.pi * self.max_frequency / c) / (
                    4 * math.pi)
            except (OverflowError, ZeroDivisionError):
                pass
            if not (math.isfinite(n_est) and n_est <= MAX_MODES):
                raise SceneError(f"plate.max_frequency gives about {n_est:.3g} modes with "
                                 f"plate.length, width, thickness, youngs_modulus, density and "
                                 f"poisson_ratio as given (limit {MAX_MODES}), lower it, got "
                                 f"{self.max_frequency} Hz")

    @property
    def bending_stiffness(self) -> float:
        """B' = E h^3 / (12 (1 - nu^2)) [N m]."""
        return self.youngs_modulus * self.thickness**3 / (12.0 * (1.0 - self.poisson_ratio**2))

    @property
    def mass_per_area(self) -> float:
        """m'' = rho h [kg/m^2]."""
        return self.density * self.thickness

    @property
    def wave_speed_factor(self) -> float:
        """sqrt(B'/m'') [m^2/s]: omega = this * k^2 for a Kirchhoff plate."""
        return math.sqrt(self.bending_stiffness / self.mass_per_area)

    def mode_omega(self, n, m):
        """omega_nm = sqrt(B'/m'') ((n pi / a)^2 + (m pi / b)^2) [rad/s], the Kirchhoff angular
        frequency of mode (n, m) of the simply supported plate (n, m >= 1: ints or arrays)."""
        c = self.wave_speed_factor
        return c * ((n * (math.pi / self.length)) ** 2 + (m * (math.pi / self.width)) ** 2)

    def keeps_mode(self, omega, max_frequency: float | None = None):
        """Whether a mode of angular frequency ``omega`` [rad/s] is below the cut
        ``max_frequency`` [Hz] (default ``plate.max_frequency``), with a relative slack of
        1e-12 so that a frequency equal to the limit up to rounding is kept."""
        fmax = self.max_frequency if max_frequency is None else max_frequency
        return omega <= 2.0 * math.pi * fmax * (1.0 + MODE_CUT_SLACK)


@dataclass(frozen=True)
class Contact:
    """Unilateral linear contact springs between block and plate.

    Attributes
    ----------
    points : int or "auto"
        Number of contact springs N_c (the N highest profile maxima under the block);
        ``"auto"`` (default; the paper hand-set 10): the expected number of micro-contacts of
        the statistical contact model at the static load m g, rounded, at least 1
        (docs/theory.md, "Contact module").
    stiffness : float or "auto"
        Total incremental contact stiffness s_total [N/m], split equally; ``"auto"``
        (default; the paper hand-set 3.1e6 N/m) takes it from the surface statistics
        (Greenwood-Williamson / Greenwood-Tripp, roughvib.physics.surface).
    selection : {"separated", "highest"}
        Which profile maxima become contact points: ``separated`` (default), the highest
        maxima at least ``min_separation`` apart; ``highest``, the paper's literal rule, the
        N highest maxima with no separation constraint.
    min_separation : float
        Minimum distance between two chosen maxima [m] (so two maxima of one asperity are not
        both taken); our choice, used by ``selection = "separated"``.
    model : {"gw", "gt"}
        Statistical contact model used when ``stiffness = "auto"``.
    summit_density, summit_radius, summit_std : float or None
        Summit parameters eta_s [1/m^2], R [m], sigma_s [m]; ``None`` derives them from the
        spectral moments of the raw surface (Nayak / McCool).
    hardness : float
        Hardness of the softer surface [Pa], for the plasticity index.
    velocity_factor : bool
        Scale the stiffness by (v_rms / 0.01 m/s)^-0.481 (the paper's elevation effect);
        default true.
    patch : {"point", "area"}
        Where a contact meets the structure: ``point`` (default), at its own point under the
        block; ``area``, every contact force is spread evenly over the block's nominal contact
        area (``block.length`` x ``block.width``, centred at ``plate.block_position``) and
        feels the area mean of the structure's displacement (docs/structures.md).
    filter : {"hertz", "none"}
        The contact filter of the kinematic input: ``hertz`` (default), each contact sees the
        surface averaged over its real contact spot, weighted by the Hertz pressure of a spot
        of radius ``spot_radius`` (docs/theory.md, "The contact filter"); ``none``, the
        surface's own heights (the paper's model).
    spot_radius : float or "auto"
        Radius a of the contact spots [m]: the contact filter's radius and the scale at which
        the summits of the statistical contact are counted. ``"auto"`` (default): the mean
        micro-contact radius of the statistical contact, found self-consistently
        (docs/theory.md, "Contact module").
    friction_moment : bool
        Let the friction force act where it does, on the plate's top surface half a thickness
        (``plate.thickness`` / 2) above its mid-plane: besides the contact forces, the modes
        are then driven by the moment of the friction force through the x-slopes of their
        shapes (the paper's extension (v), docs/structures.md). Default false (the paper's
        model: friction acts on the block only). Needs a force-driven block and
        ``solver.method`` "ida" or "adaptive-modal".
    """

    points: int | str = "auto"
    stiffness: float | str = "auto"
    min_separation: float = 0.2e-3
    model: str = "gw"
    summit_density: float | None = None
    summit_radius: float | None = None
    summit_std: float | None = None
    hardness: float = 3e9
    velocity_factor: bool = True
    selection: str = "separated"
    patch: str = "point"
    filter: str = "hertz"
    spot_radius: float | str = "auto"
    friction_moment: bool = False

    def __post_init__(self) -> None:
        _set(self, "patch", _choice("contact.patch", self.patch, ("point", "area")))
        _set(self, "filter", _choice("contact.filter", self.filter, ("hertz", "none")))
        _set(self, "spot_radius",
             _auto_or_positive("contact.spot_radius", self.spot_radius, "m"))
        _set(self, "friction_moment", _boolean("contact.friction_moment", self.friction_moment))
        if isinstance(self.points, str):
            _choice("contact.points", self.points, ("auto",))
        else:
            _set(self, "points", _integer("contact.points", self.points, 1, MAX_CONTACTS))
        if isinstance(self.stiffness, str):
            _choice("contact.stiffness", self.stiffness, ("auto",))
        else:
            _set(self, "stiffness", _positive("contact.stiffness", self.stiffness, "N/m"))
        _set(self, "min_separation",
             _nonneg("contact.min_separation", self.min_separation, "m"))
        _set(self, "model", _choice("contact.model", self.model, ("gw", "gt")))
        _set(self, "summit_density",
             _opt_positive("contact.summit_density", self.summit_density, "1/m^2"))
        _set(self, "summit_radius",
             _opt_positive("contact.summit_radius", self.summit_radius, "m"))
        _set(self, "summit_std", _opt_positive("contact.summit_std", self.summit_std, "m"))
        _set(self, "hardness", _positive("contact.hardness", self.hardness, "Pa"))
        _set(self, "velocity_factor", _boolean("contact.velocity_factor", self.velocity_factor))
        _set(self, "selection", _choice("contact.selection", self.selection,
                                        ("separated", "highest")))
        _check_bounds(self, "contact")


@dataclass(frozen=True)
class Roughness:
    """Roughness profile z(s) (height, positive up) along the sliding direction.

    Attributes
    ----------
    kind : {"none", "sinusoid", "synthetic", "file"}
    interpolation : {"cubic", "linear", "quintic"}
        Interpolant between the samples of the input grid: ``quintic`` (default), a C4
        spline, whose knots an error-controlled step does not feel; ``cubic``, C2 (its
        third derivative jumps at every knot, which tight tolerances pay for in steps);
        ``linear``, C0, the paper's.
    amplitude, wavelength : float
        ``sinusoid``: z = amplitude cos(2 pi s / wavelength) [m], [m].
    rms : float
        ``synthetic``: rms of the kinematic input profile [m] (the 2-D reduced profile).
    seed : int
        ``synthetic``: random seed.
    hurst : float
        Hurst exponent H of the self-affine PSD tail, slope -(1 + 2H).
    rolloff_wavelength : float
        lambda_0 [m]: flat PSD above it, power law below it.
    shortest_wavelength : float or "auto"
        Where the surface's self-affine tail stops [m]. ``"auto"`` (default): the wavelength
        that the rms sliding speed maps to the top of the output band (v_rms / (2
        output.step): 0.2 um at 10 mm/s), at most 50 um, so that no band shown depends on it
        (docs/surfaces.md); 50e-6 is the paper's measured band.
    longest_wavelength : float
        Long end of the band [m] (40 mm, the block length, in the paper).
    spacing : float or "auto"
        Grid spacing of the input [m]: the field is sampled on it and interpolated between
        the samples (``synthetic``); the sample spacing of a one-column ``file``. ``"auto"``
        (default): a quarter of the shortest wavelength with the contact filter, an eighth without
        (``synthetic``), the paper's 10 um for a one-column file and the other kinds.
    trace_length : float
        Length of the synthetic trace [m].
    raw_rms : float
        Combined rms of the raw (3-D) surface [m]; feeds contact stiffness "auto" and the
        3-D surface generated when ``reduce_3d`` is true.
    reduce_3d : bool
        Generate an isotropic 2-D surface of rms ``raw_rms`` and reduce it to the input profile
        by span-averaging across the block width (then ``rms`` is not used).
    trace_layout : {"uniform", "cbrt2"}
        ``reduce_3d``: where the averaged traces lie across the width. ``uniform`` (default):
        a pitch of ``spacing``, the continuous width average of docs/theory.md (about
        -23 dB for the default surface). ``cbrt2``: the paper's separations growing by
        2^(1/3) from one edge, averaged with trapezoidal weights (about -10 dB; the paper
        used that layout for a coherence integral, see docs/theory.md).
    filter : {"highpass", "block-lowpass", "none"}
        Functional filter over the block length (docs/theory.md).
    tail : {"fit", "none"}
        ``file``: below the shortest wavelength the samples resolve (twice their spacing),
        ``fit`` (default) continues the profile's spectrum with the self-affine slope fitted
        to its own shortest resolved decade, down to ``shortest_wavelength`` (random phases
        from ``seed``); ``none`` keeps the file's band alone (the bands above v / (2 dx) then
        hold only the interpolant's residue).
    path : str
        ``file``: path of a profile file (relative paths are relative to the scene file).
    units : {"m", "um", "nm"}
        ``file``, text format: height unit of the file (and of the x column, if given).
    format : {"auto", "text", "topography"}
        ``file``: ``text`` is the plain-text/CSV reader; ``topography`` reads instrument
        formats (ISO 25178-71 SDF, X3P, Digital Surf .sur, Zygo .datx, ...) through the
        optional SurfaceTopography package (``pip install roughvib[topography]``); the x axis
        of the map is the sliding direction and units come from the file. ``auto``: by the
        file suffix (instrument suffixes -> topography) and content (netCDF or HDF5, e.g.
        SurfaceTopography's own ``.nc`` from contact.engineering -> topography), anything
        else -> text.
    """

    kind: str = "synthetic"
    interpolation: str = "quintic"
    amplitude: float = 0.35e-6
    wavelength: float = 1e-3
    rms: float = 0.35e-6
    seed: int = 1
    hurst: float = 0.8
    rolloff_wavelength: float = 0.5e-3
    shortest_wavelength: float | str = "auto"
    longest_wavelength: float = 0.04
    spacing: float | str = "auto"
    trace_length: float = 0.16
    raw_rms: float = 3.5e-6
    reduce_3d: bool = False
    trace_layout: str = "uniform"
    filter: str = "highpass"
    tail: str = "fit"
    path: str = ""
    units: str = "m"
    format: str = "auto"

    def __post_init__(self) -> None:
        p = "roughness"
        _set(self, "kind", _choice(f"{p}.kind", self.kind,
                                   ("none", "sinusoid", "synthetic", "file")))
        _set(self, "interpolation", _choice(f"{p}.interpolation", self.interpolation,
                                            ("cubic", "linear", "quintic")))
        _set(self, "amplitude", _nonneg(f"{p}.amplitude", self.amplitude, "m"))
        _set(self, "wavelength", _positive(f"{p}.wavelength", self.wavelength, "m"))
        _set(self, "rms", _nonneg(f"{p}.rms", self.rms, "m"))
        _set(self, "seed", _integer(f"{p}.seed", self.seed, 0))
        _set(self, "hurst", _range(f"{p}.hurst", self.hurst, 0.0, 1.0, "", lo_open=True))
        _set(self, "rolloff_wavelength",
             _positive(f"{p}.rolloff_wavelength", self.rolloff_wavelength, "m"))
        _set(self, "shortest_wavelength",
             _auto_or_positive(f"{p}.shortest_wavelength", self.shortest_wavelength, "m"))
        _set(self, "longest_wavelength",
             _positive(f"{p}.longest_wavelength", self.longest_wavelength, "m"))
        _set(self, "spacing", _auto_or_positive(f"{p}.spacing", self.spacing, "m"))
        _set(self, "trace_length", _positive(f"{p}.trace_length", self.trace_length, "m"))
        _set(self, "raw_rms", _nonneg(f"{p}.raw_rms", self.raw_rms, "m"))
        _set(self, "reduce_3d", _boolean(f"{p}.reduce_3d", self.reduce_3d))
        _set(self, "trace_layout", _choice(f"{p}.trace_layout", self.trace_layout,
                                           ("uniform", "cbrt2")))
        _set(self, "filter", _choice(f"{p}.filter", self.filter,
                                     ("highpass", "block-lowpass", "none")))
        _set(self, "tail", _choice(f"{p}.tail", self.tail, ("fit", "none")))
        if not isinstance(self.path, str):
            raise SceneError(f"{p}.path must be a string (file path), got {_fmt(self.path)}")
        _set(self, "units", _choice(f"{p}.units", self.units, ("m", "um", "nm")))
        _set(self, "format", _choice(f"{p}.format", self.format,
                                     ("auto", "text", "topography")))
        _check_bounds(self, "roughness")
        numeric = not isinstance(self.shortest_wavelength, str)
        if numeric and self.shortest_wavelength >= self.longest_wavelength:
            raise SceneError(f"{p}.shortest_wavelength must be < roughness.longest_wavelength "
                             f"({self.longest_wavelength} m), got {self.shortest_wavelength} m")
        if (self.kind == "synthetic" and numeric and not isinstance(self.spacing, str)
                and self.shortest_wavelength < 2 * self.spacing):
            raise SceneError(f"{p}.shortest_wavelength must be >= 2 * roughness.spacing "
                             f"({2 * self.spacing} m), got {self.shortest_wavelength} m")
        if self.kind == "file" and not self.path:
            raise SceneError(f"{p}.path must name a profile file when roughness.kind = "
                             f"'file', got ''")
