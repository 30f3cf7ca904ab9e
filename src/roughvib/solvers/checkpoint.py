"""Checkpoints of the event-driven solvers: what a run needs to continue where it stopped.

A checkpoint is one file, ``checkpoint.pkl`` in the run's output directory, replaced
atomically (written to a temporary file in the same directory, then ``os.replace``), so a run
killed while writing leaves the previous checkpoint intact. It holds the scene (TOML text), the
output rows already filled, the event log, the statistics, the discrete regime and the
continuous state at a grid time t_c, and the solver's own loop state. IDA is restarted at t_c
from a consistent state both in the run that wrote it and in the run that resumes from it; the
adaptive exact-modal scheme, a one-step method, stores everything its loop carries from one
step to the next. Either way the resumed run is identical to the uninterrupted one
(docs/robustness.md).
It also records what the run read besides the scene (the SHA-256 of a roughness file), the
code that ran it (:func:`code_identity`) and the SHA-256 of the run directory's ``scene.toml``
(an earlier run's, if any), and :func:`check_inputs` refuses to resume when any of them has
changed: an edited ``scene.toml`` would otherwise look as if the resumed run used it.

The file is a header line ``roughvib-checkpoint``, a line with the format version, the
SHA-256 and the length of what follows, and then a Python pickle of the :class:`Checkpoint`.
:func:`read_checkpoint` unpickles only a file whose header and digest match: an empty,
truncated, damaged or foreign file is refused in one line naming it, before any unpickling.
The digest detects damage, not intent: a pickle runs code when it is loaded, so load only
checkpoints you made.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import tempfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from roughvib._errors import write_failed
from roughvib.scene import Scene, SceneError, scene_to_toml

if TYPE_CHECKING:  # the model (numba kernels) is needed only to start a run, not to name
    # a checkpoint file: roughvib.rundir reads CHECKPOINT_NAME before any heavy import
    from roughvib.model.regimes import Regime
    from roughvib.model.system import System

__all__ = ["CHECKPOINT_NAME", "CHECKPOINT_VERSION", "Checkpoint", "check_checkpoint_file",
           "check_inputs", "check_resume", "code_identity", "input_fingerprint",
           "read_checkpoint", "start_state", "write_checkpoint"]

CHECKPOINT_NAME = "checkpoint.pkl"
#: 2: header line, version / SHA-256 / length line, pickle (1: a pickled dict, no digest)
CHECKPOINT_VERSION = 2
_MAGIC = "roughvib-checkpoint"
_HEADER = _MAGIC.encode() + b"\n"


@dataclass
class Checkpoint:
    """State of an event-driven run at a checkpoint time.

    Attributes
    ----------
    scene_toml : str
        The scene as given to the run (before calibration), TOML text.
    t : float
        Checkpoint time t_c [s], a grid time.
    k : int
        Index of the next output row to fill (grid[k - 1] == t).
    y : ndarray, shape (n_states,)
        State at t_c (IDA's, before the consistent restart).
    y_initial : ndarray, shape (n_states,)
        State at t = 0 (energy audit).
    outputs : ndarray, shape (k, n_out)
        Output rows 0 .. k-1.
    reg, rf : ndarray
        The kernels' regime arrays (int and float).
    regime : object
        The :class:`~roughvib.model.regimes.Regime`.
    events : list
        :class:`~roughvib.solvers.events.EventRecord` so far.
    stats : dict
        Solver statistics so far (counts; wall time of the earlier processes).
    loop : dict
        Event-loop bookkeeping and what the solver (``scene_toml``'s ``solver.method``)
        carries between steps. IDA: ``recent`` (event times in the storm window),
        ``t_last_restart``, ``last_fired``, ``refire_ignored``, ``h_restart``.
        adaptive-modal: ``recent``, the integer loop state ``ist`` (step level, counters),
        and the derivatives ``d``, modal forces ``u``, margins ``g`` and armed roots
        ``armed`` of the state.
    force_amplitude : float
        T0 [N] of the run (resuming checks it is reproduced).
    base_dir : str
        Directory relative paths of the scene (roughness files) are resolved against.
    inputs : dict
        What the run depends on besides the code, from :func:`input_fingerprint`.
    """

    scene_toml: str
    t: float
    k: int
    y: np.ndarray
    y_initial: np.ndarray
    outputs: np.ndarray
    reg: np.ndarray
    rf: np.ndarray
    regime: object
    events: list
    stats: dict
    loop: dict = field(default_factory=dict)
    force_amplitude: float = float("nan")
    base_dir: str = "."
    inputs: dict = field(default_factory=dict)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def source_digest(root: Path) -> str:
    """SHA-256 over the relative path and the bytes of every ``.py`` file under ``root``.

    Files are taken in path order, so the digest changes when a source file is changed,
    added, removed or renamed, and not when only compiled caches or data files change.
    """
    h = hashlib.sha256()
    for f in sorted(Path(root).rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(f.read_bytes()).digest())
    return h.hexdigest()


@functools.cache
def code_identity() -> dict:
    """The code a run executes: roughvib's version and sources, and the numerical libraries.

    Returns
    -------
    dict
        ``roughvib`` (version), ``roughvib_sources`` (SHA-256 over the relative path and bytes
        of every ``.py`` file of the installed package, in path order: a changed, added or
        removed source file changes it, also between two commits of one version) and the
        versions of numpy, scipy, numba and llvmlite (scikit-sundae's is added by
        :func:`input_fingerprint` for IDA's checkpoints).
    """
    from roughvib._cache import library_versions
    from roughvib._version import __version__

    return {"roughvib": __version__,
            "roughvib_sources": source_digest(Path(__file__).resolve().parent.parent),
            **library_versions()}


@functools.cache
def _sundae_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("scikit-sundae")
    except PackageNotFoundError:
        return "not installed"


def input_fingerprint(scene_toml: str, profile_stats: dict, *, ida: bool = False) -> dict:
    """What a run depends on: the scene (its TOML text), a roughness file's contents, the code.

    Parameters
    ----------
    scene_toml : str
        The scene as stored in the checkpoint.
    profile_stats : dict
        ``Profile.stats`` of the run: ``path`` and ``sha256`` of the bytes read from a
        roughness file (absent for synthetic profiles).
    ida : bool, optional
        The checkpoint is IDA's: scikit-sundae's version is part of the code.

    Returns
    -------
    dict
        ``scene_sha256``, ``code`` (:func:`code_identity`) and, with a roughness file,
        ``roughness_file`` = ``{"path", "sha256"}``.
    """
    code = dict(code_identity())
    if ida:
        code["scikit-sundae"] = _sundae_version()
    out: dict = {"scene_sha256": _sha256(scene_toml.encode()), "code": code}
    if profile_stats.get("sha256"):
        out["roughness_file"] = {"path": str(profile_stats["path"]),
                                 "sha256": profile_stats["sha256"]}
    return out


def check_inputs(cp: Checkpoint, scene: Scene, path: Path) -> None:
    """Refuse to resume if an input of the checkpoint's run has changed since it was written.

    Parameters
    ----------
    cp : Checkpoint
    scene : Scene
        The scene stored in the checkpoint.
    path : Path
        The checkpoint file (for the message).

    Raises
    ------
    SceneError
        One line: the scene text is damaged; the run directory's ``scene.toml`` was edited
        (or appeared) since the checkpoint was written; the code that wrote the checkpoint
        (roughvib's version or sources, a numerical library's version) is not the code
        resuming it, or was not recorded (an older roughvib); or the roughness file is
        missing, changed, or was not recorded.
    """
    again = "start the run again without --resume"
    recorded = cp.inputs.get("scene_sha256")
    if recorded is not None and recorded != _sha256(cp.scene_toml.encode()):
        raise SceneError(f"{path}: the checkpoint's scene does not match its recorded SHA-256 "
                         f"(a damaged file); {again}")
    then, now = cp.inputs.get("code"), dict(code_identity())
    if then is None:
        raise SceneError(f"{path}: the checkpoint does not record the code that wrote it (an "
                         f"older roughvib), so the resumed run could mix the results of two "
                         f"versions; {again}")
    if "scikit-sundae" in then:  # IDA's checkpoint
        now["scikit-sundae"] = _sundae_version()
    changed = [k for k in sorted(set(then) | set(now)) if then.get(k) != now.get(k)]
    _check_directory_scene(cp, path)
    if changed:
        def show(v):
            return "none" if v is None else (v[:12] + "..." if len(str(v)) > 16 else v)

        what = ", ".join(f"{k} {show(then.get(k))} then, {show(now.get(k))} now"
                         for k in changed)
        raise SceneError(f"{path}: written by other code ({what}): the resumed run would mix "
                         f"the results of two versions; resume with the code that wrote it or "
                         f"{again}")
    if scene.roughness.kind != "file":
        return
    rec = cp.inputs.get("roughness_file")
    if not rec:
        raise SceneError(f"{path}: the checkpoint records no SHA-256 of roughness.path (an "
                         f"older roughvib wrote it), so an edited profile file would go "
                         f"unnoticed; {again}")
    try:
        now = _sha256(Path(rec["path"]).read_bytes())
    except OSError as exc:
        raise SceneError(f"roughness.path {rec['path']} cannot be read ({exc.strerror}): the "
                         f"checkpoint in {path.parent} was written with it; restore it or "
                         f"{again}") from None
    if now != rec["sha256"]:
        raise SceneError(f"roughness.path {rec['path']} changed since the checkpoint was "
                         f"written (SHA-256 {rec['sha256'][:12]}... then, {now[:12]}... now): "
                         f"restore it or {again}")


#: key of ``Checkpoint.inputs``: the SHA-256 of the run directory's ``scene.toml`` when the
#: checkpoint was written, ``"absent"`` if there was none (see :func:`write_checkpoint`)
DIRECTORY_SCENE = "directory_scene_toml"


def _scene_file_digest(directory: Path) -> str | None:
    """SHA-256 of ``directory/scene.toml``; ``"absent"`` without one, ``"not a regular file"``
    for anything else there, None if it cannot be read (then nothing is compared). Never
    raises and never blocks: a run's checkpoint must not fail over this file."""
    import stat

    try:
        fd = os.open(directory / "scene.toml", os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        return "absent"
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return "not a regular file"
        h = hashlib.sha256()
        while chunk := os.read(fd, 1 << 20):
            h.update(chunk)
        return h.hexdigest()
    except OSError:
        return None
    finally:
        os.close(fd)


def _check_directory_scene(cp: Checkpoint, path: Path) -> None:
    """Refuse to resume when the run directory's scene.toml changed since the checkpoint: a
    user who edited it would believe the resumed run uses it, and --resume runs the scene
    stored in the checkpoint."""
    then = cp.inputs.get(DIRECTORY_SCENE)
    if then is None:  # an older checkpoint, or unreadable then: nothing to compare
        return
    now = _scene_file_digest(path.parent)
    if now is None or now == then or now == "absent":  # removed: nothing that misleads
        return
    scene_file = path.parent / "scene.toml"

    def show(d):
        return d if d in ("absent", "not a regular file") else f"SHA-256 {d[:12]}..."

    raise SceneError(f"{scene_file} changed since the checkpoint was written ({show(then)} "
                     f"then, {show(now)} now): --resume continues the scene stored in {path}, "
                     f"not that file; restore it, or run the edited scene as a new run "
                     f"('roughvib run {scene_file} --out NEW_DIR')")


def check_resume(cp: Checkpoint, system: System, n: int, n_out: int) -> None:
    """A checkpoint must belong to this scene and fit its grid (else a one-line error)."""
    if scene_to_toml(system.scene) != cp.scene_toml:
        raise SceneError("the checkpoint was written by a different scene; resume with the "
                         "scene stored in the checkpoint (roughvib run --resume DIR)")
    if not (1 <= cp.k < n) or cp.outputs.shape != (cp.k, n_out) or \
            cp.y.shape != (system.layout.size,):
        raise SceneError(f"the checkpoint does not fit this model (rows {cp.outputs.shape}, "
                         f"{cp.y.shape[0]} states; expected {n} rows of {n_out} outputs and "
                         f"{system.layout.size} states)")
    if not np.isnan(cp.force_amplitude) and cp.force_amplitude != system.force_amplitude:
        raise SceneError(f"the checkpoint's force amplitude {cp.force_amplitude!r} N differs "
                         f"from the recalibrated {system.force_amplitude!r} N")


def start_state(system: System, reg: np.ndarray, rf: np.ndarray, resume: Checkpoint | None,
                n: int, n_out: int) -> tuple[Regime, np.ndarray, np.ndarray]:
    """Where an event-driven run starts: the regime (packed into ``reg``, ``rf``), the state
    and the state at t = 0 (energy audit).

    Without ``resume``: the static equilibrium at t = 0, made consistent. With it: the
    checkpoint's, once :func:`check_resume` has accepted it for this scene and a grid of
    ``n`` rows of ``n_out`` outputs.
    """
    if resume is None:
        from roughvib.model.regimes import initial_regime

        y0, closed = system.static_equilibrium()
        regime = initial_regime(closed, system.fp, system.layout.tangential,
                                system.scene.friction.law)
        regime.pack(reg, rf)
        y, _ = system.consistent(0.0, y0, reg, rf)
        return regime, y, y.copy()
    check_resume(resume, system, n, n_out)
    reg[:] = resume.reg
    rf[:] = resume.rf
    return (resume.regime, np.array(resume.y, dtype=float),
            np.array(resume.y_initial, dtype=float))


def write_checkpoint(directory: str | os.PathLike, cp: Checkpoint) -> Path:
    """Write ``directory/checkpoint.pkl`` atomically; return its path.

    The file is the header line, ``<version> <sha256> <bytes>`` of the pickle, and the pickle
    of ``cp`` (see the module docstring).

    Raises
    ------
    roughvib.rundir.WriteError
        The file could not be written (a full disk, a read-only file system): one line naming
        the checkpoint's path and why, for a full disk also its size and the space free. The
        checkpoint written before it stays, and no temporary file is left.
    """
    out = Path(directory)
    path = out / CHECKPOINT_NAME
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise write_failed(path, exc) from None
    # what the directory's scene.toml was when the checkpoint was written (an earlier run's,
    # or none): a resume refuses if it was edited, since --resume runs the checkpoint's scene
    cp = replace(cp, inputs={**cp.inputs, DIRECTORY_SCENE: _scene_file_digest(out)})
    payload = pickle.dumps(cp, protocol=pickle.HIGHEST_PROTOCOL)
    head = _HEADER + f"{CHECKPOINT_VERSION} {_sha256(payload)} {len(payload)}\n".encode()
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{CHECKPOINT_NAME}.", dir=out)
    except OSError as exc:
        raise write_failed(path, exc, len(head) + len(payload)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(head)
            fh.write(payload)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise write_failed(path, exc, len(head) + len(payload)) from None
        raise
    return path


def _read_head(fh, path: Path) -> tuple[str, int]:
    """The digest and length of the pickle after a checkpoint's header (SceneError if the
    file is not a checkpoint of this format)."""
    again = "run the scene again"
    first = fh.readline(len(_HEADER))
    if first != _HEADER:
        fh.seek(0)
        start = fh.read(256)
        if not start:
            raise SceneError(f"{path}: an empty file, not a roughvib checkpoint (roughvib "
                             f"replaces its checkpoints whole, never leaves one empty)")
        if start[:1] == b"\x80" and _MAGIC.encode() in start:
            raise SceneError(f"{path}: checkpoint format version 1 (an older roughvib) cannot "
                             f"be resumed by this roughvib (format {CHECKPOINT_VERSION}); "
                             f"{again}")
        raise SceneError(f"{path}: not a roughvib checkpoint (it does not start with the "
                         f"'{_MAGIC}' header); resume only a directory a roughvib run wrote "
                         f"checkpoints into")
    line = fh.readline(200)
    parts = line.decode("ascii", errors="replace").split()
    if len(parts) != 3:
        parts = ["", "", ""]  # refused just below
    version, digest, size = parts
    if not version.isdigit() or not size.isdigit() or len(digest) != 64:
        raise SceneError(f"{path}: a damaged roughvib checkpoint (its second header line is "
                         f"not '<version> <sha256> <bytes>'); {again}")
    if int(version) != CHECKPOINT_VERSION:
        raise SceneError(f"{path}: checkpoint format version {version} cannot be resumed by "
                         f"this roughvib (format {CHECKPOINT_VERSION}); {again}")
    return digest, int(size)


def _open_regular(path: Path):
    """``path`` opened for reading if it is a regular file (checked on the open descriptor,
    opened without blocking: a named pipe would wait for a writer forever), else SceneError."""
    import stat

    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise SceneError(f"{path}: not a regular file, so not a roughvib checkpoint; "
                             f"resume only a directory a roughvib run wrote checkpoints into")
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_checkpoint_file(path: str | os.PathLike) -> None:
    """Check a checkpoint file's header, format version and length without unpickling it.

    Parameters
    ----------
    path : path
        The checkpoint file (``DIR/checkpoint.pkl``).

    Raises
    ------
    SceneError
        Missing, unreadable, empty, foreign, of another format version, or truncated (one
        line naming the file).
    """
    path = Path(path)
    try:
        with _open_regular(path) as fh:
            _, length = _read_head(fh, path)
            pos = fh.tell()
            size = fh.seek(0, os.SEEK_END)
    except FileNotFoundError:
        raise SceneError(f"{path}: no checkpoint to resume from (a run writes one when "
                         f"output.checkpoint_interval > 0 s)") from None
    except OSError as exc:
        raise SceneError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if size - pos != length:
        raise SceneError(f"{path}: a truncated or damaged roughvib checkpoint ({size - pos} "
                         f"bytes after the header, {length} written); run the scene again")


def read_checkpoint(directory: str | os.PathLike) -> Checkpoint:
    """Read ``directory/checkpoint.pkl``.

    The pickle is loaded only after the header, the format version, the length and the
    SHA-256 of the file have been checked.

    Raises
    ------
    SceneError
        No checkpoint, an unreadable, empty, truncated, damaged or foreign file, or one written
        by another checkpoint version (one line naming the file and the problem).
    """
    path = Path(directory) / CHECKPOINT_NAME
    if not path.is_file():
        raise SceneError(f"{path}: no checkpoint to resume from (a run writes one when "
                         f"output.checkpoint_interval > 0 s)")
    again = "run the scene again"
    try:
        with _open_regular(path) as fh:
            digest, length = _read_head(fh, path)
            payload = fh.read()
    except OSError as exc:
        raise SceneError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if len(payload) != length:
        raise SceneError(f"{path}: a truncated or damaged roughvib checkpoint ({len(payload)} "
                         f"bytes after the header, {length} written); {again}")
    if _sha256(payload) != digest:
        raise SceneError(f"{path}: a damaged roughvib checkpoint (its contents do not match "
                         f"the SHA-256 in its header); {again}")
    try:
        cp = pickle.loads(payload)
    except Exception as exc:  # written by roughvib, intact, yet unreadable: other code
        raise SceneError(f"{path}: the checkpoint cannot be read by this roughvib "
                         f"({type(exc).__name__}: {' '.join(str(exc).split())[:120]}); "
                         f"{again}") from None
    if not isinstance(cp, Checkpoint):
        raise SceneError(f"{path}: not a roughvib checkpoint (it holds a "
                         f"{type(cp).__name__}); {again}")
    return cp
