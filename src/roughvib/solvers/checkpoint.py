"""Checkpoints of the event-driven IDA loop: what a run needs to continue where it stopped.

A checkpoint is one file, ``checkpoint.pkl`` in the run's output directory, replaced
atomically (written to a temporary file in the same directory, then ``os.replace``), so a run
killed while writing leaves the previous checkpoint intact. It holds the scene (TOML text), the
output rows already filled, the event log, the statistics, the discrete regime and the
continuous state at a grid time t_c; IDA is restarted at t_c from a consistent state both in
the run that wrote it and in the run that resumes from it, which is why the two give identical
results (docs/robustness.md).

The file is a Python pickle written by roughvib for roughvib: load only checkpoints you made.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from roughvib.scene import SceneError

__all__ = ["CHECKPOINT_NAME", "CHECKPOINT_VERSION", "Checkpoint", "read_checkpoint",
           "write_checkpoint"]

CHECKPOINT_NAME = "checkpoint.pkl"
CHECKPOINT_VERSION = 1
_MAGIC = "roughvib-checkpoint"


@dataclass
class Checkpoint:
    """State of an IDA run at a checkpoint time.

    Attributes
    ----------
    scene_toml : str
        The scene as given to the run (before calibration), TOML text.
    t : float
        Checkpoint time t_c [s], a grid time.
    k : int
        Index of the next output row to fill (grid[k - 1] == t).
    y : ndarray, shape (n_states,)
        State returned by IDA at t_c (before the consistent restart).
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
        Event-loop bookkeeping: ``recent`` (event times in the storm window),
        ``t_last_restart``, ``last_fired``, ``refire_ignored``.
    force_amplitude : float
        T0 [N] of the run (resuming checks it is reproduced).
    base_dir : str
        Directory relative paths of the scene (roughness files) are resolved against.
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


def write_checkpoint(directory: str | os.PathLike, cp: Checkpoint) -> Path:
    """Write ``directory/checkpoint.pkl`` atomically; return its path."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    path = out / CHECKPOINT_NAME
    fd, tmp = tempfile.mkstemp(prefix=f".{CHECKPOINT_NAME}.", dir=out)
    try:
        with os.fdopen(fd, "wb") as fh:
            pickle.dump({"magic": _MAGIC, "version": CHECKPOINT_VERSION, "checkpoint": cp},
                        fh, protocol=pickle.HIGHEST_PROTOCOL)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def read_checkpoint(directory: str | os.PathLike) -> Checkpoint:
    """Read ``directory/checkpoint.pkl``.

    Raises
    ------
    SceneError
        No checkpoint, an unreadable file, or one written by another checkpoint version (one
        line naming the file and the problem).
    """
    path = Path(directory) / CHECKPOINT_NAME
    if not path.is_file():
        raise SceneError(f"{path}: no checkpoint to resume from (a run writes one when "
                         f"output.checkpoint_interval > 0 s)")
    try:
        with path.open("rb") as fh:
            data = pickle.load(fh)
    except Exception as exc:  # a truncated or foreign file: any unpickling error
        raise SceneError(f"{path}: not a readable roughvib checkpoint "
                         f"({type(exc).__name__})") from None
    if not isinstance(data, dict) or data.get("magic") != _MAGIC:
        raise SceneError(f"{path}: not a roughvib checkpoint")
    if data.get("version") != CHECKPOINT_VERSION:
        raise SceneError(f"{path}: checkpoint format version {data.get('version')} cannot be "
                         f"resumed by this roughvib (format {CHECKPOINT_VERSION}); run the "
                         f"scene again")
    return data["checkpoint"]
