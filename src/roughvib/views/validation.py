"""Validation of a run against measured records: the figure, the files and the report section.

``validate(RUN_DIR, files, signal=...)`` is what ``roughvib validate`` does: for each measured
record (:func:`roughvib.records.read_record`) it compares the record with the run
(:func:`roughvib.analysis.validation.compare_record`) and writes
``RUN_DIR/validation/<file stem>/``:

* ``bands.csv``: ``band_hz, simulated_db, measured_db, difference_db, noise_db,
  at_noise_floor`` (levels in dB re 1e-6 m/s^2, difference = measured - simulated);
* ``validation.png``: third-octave and narrow-band spectra of both (:func:`plot_validation`,
  after the paper's Figs. 14/15);
* ``validation.json``: the overall levels and their difference, the bands left out and why, the
  windows, rates, units and noise floor, and the one-line summary.

With records of runs at two or more friction velocities, :func:`velocity_exponent_of`
gives the velocity exponents (dB per doubling) of measured and simulated levels.
:func:`validation_section` is the run report's section listing every validation of a run.
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING

from roughvib.analysis.validation import (
    Validation,
    compare_record,
    validation_velocity_exponent,
)
from roughvib.records import RecordError, read_record

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

__all__ = ["VALIDATION_DIR", "plot_validation", "read_validations", "validate",
           "validation_section", "velocity_exponent_of"]

#: the folder of a run directory that holds its validations
VALIDATION_DIR = "validation"


def plot_validation(v: Validation, *, axes=None) -> list[Axes]:
    """Simulated and measured spectra overlaid (after the paper's Figs. 14/15).

    Left: third-octave band levels of the compared bands, the noise floor if one was given
    (bands within the margin of it marked); right: Welch narrow-band densities of both
    windows.

    Parameters
    ----------
    v : Validation
        From :func:`roughvib.analysis.validation.compare_record`.
    axes : sequence of 2 Axes, optional
        [third-octave, narrow band]; new ones if None.

    Returns
    -------
    list of Axes
    """
    from roughvib.views.figures import _axes, _plt

    if axes is None:
        _, axes = _plt().subplots(1, 2, figsize=(11, 4.2))
    axes = _axes(axes, 2, None)
    t = v.table
    name = Path(v.record).name
    f = t["band_hz"].to_numpy(dtype=float)
    ax = axes[0]
    ax.step(f, t["simulated_db"], where="mid", color="C3", lw=1.6,
            label=f"simulated {v.signal}, band sum {v.overall_simulated_db:.1f} dB")
    ax.step(f, t["measured_db"], where="mid", color="k", lw=1.0, ls=(0, (4, 2)),
            label=f"measured ({name}), band sum {v.overall_measured_db:.1f} dB")
    if v.noise:
        ax.step(f, t["noise_db"], where="mid", color="0.6", lw=0.8, ls="--",
                label="noise floor")
        at = t["at_noise_floor"].fillna(False).to_numpy(dtype=bool)
        if at.any():
            ax.plot(f[at], t["measured_db"].to_numpy()[at], "o", mfc="none", color="0.4",
                    ms=5, label=f"within {v.margin_db:g} dB of the floor")
    ax.set_ylabel("third-octave level [dB re 1e-6 m/s²]")
    diff = round(v.overall_difference_db, 1) + 0.0  # no "-0.0"
    ax.set_title(f"third-octave bands: measured − simulated {diff:+.1f} dB overall",
                 fontsize=9)
    if len(f):
        ax.set_xlim(f[0] / 1.15, f[-1] * 1.15)
    ax = axes[1]
    ax.plot(v.frequency_run[1:], v.psd_run[1:], color="C3", lw=0.8, label="simulated")
    ax.plot(v.frequency_record[1:], v.psd_record[1:], color="k", lw=0.5, ls=(0, (4, 2)),
            label="measured")
    ax.set_ylabel("PSD [dB re (1e-6 m/s²)²/Hz]")
    df = v.frequency_record[1] - v.frequency_record[0]
    ax.set_title(f"narrow band, Welch Hann, Δf = {df:.3g} Hz; window {v.window_s:.3g} s",
                 fontsize=9)
    ax.set_xlim(max(v.frequency_run[1], 10.0),
                max(v.frequency_run[-1], v.frequency_record[-1]))
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("frequency [Hz]")
        ax.legend(fontsize=7, loc="lower left")
    return axes


def _stem(path: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(path).stem) or "record"


def _write(v: Validation, folder: Path, dpi: int) -> Path:
    """The files of one validation in ``folder`` (roughvib's own, replaced by a new
    validation of the same record); each appears complete or not at all."""
    from roughvib.rundir import output_folder, writing
    from roughvib.views.figures import _plt

    output_folder(folder)
    table = v.table.copy()
    with writing(folder / "bands.csv", newline="") as fh:
        table.to_csv(fh, index=False, float_format="%.4f")
    plt = _plt()
    fig = plot_validation(v)[0].figure
    try:
        fig.suptitle(f"{v.signal} acceleration: run {v.info.get('scene')} "
                     f"({v.info.get('run_id')}) vs {Path(v.record).name}", fontsize=10)
        fig.tight_layout()
        with writing(folder / "validation.png", "wb") as fh:
            fig.savefig(fh, dpi=dpi, format="png")
    finally:
        plt.close(fig)
    summary = v.to_summary()
    summary["files"] = {"bands": "bands.csv", "figure": "validation.png"}
    with writing(folder / "validation.json") as fh:
        fh.write(json.dumps(summary, indent=2, default=float))
    return folder


def validate(run_dir: str | os.PathLike, files, *, signal: str = "plate",
             column: str | int | None = None, units: str | None = None,
             scale: float | None = None, noise: str | os.PathLike | None = None,
             noise_rms: float | None = None, margin_db: float = 6.0,
             start: float | None = None, fmax: float | None = None,
             dpi: int = 100) -> list[Validation]:
    """Compare measured records with a run and write ``RUN_DIR/validation/<stem>/``.

    Parameters
    ----------
    run_dir : path
        A complete run (``roughvib run``).
    files : path or list of paths
        Measured acceleration records (:func:`roughvib.records.read_record`).
    signal : {'plate', 'block'}
        The run's signal the records measured.
    column, units, scale
        Passed to :func:`~roughvib.records.read_record` for every record (and the noise
        record).
    noise : path, optional
        A measured noise record (same channel, no excitation) as the noise floor.
    noise_rms : float, optional
        Or a white noise floor of this rms [m/s^2].
    margin_db : float
        Bands within this of the floor are marked ``at_noise_floor`` [dB].
    start : float, optional
        Start of each record's window from its first sample [s] (default: the run's).
    fmax : float, optional
        Highest band to compare [Hz] (default: the run's highest).
    dpi : int
        Resolution of ``validation.png``.

    Returns
    -------
    list of Validation
        One per record, in the order given.

    Raises
    ------
    RecordError
        One line naming the file that cannot be compared (nothing is written for it, nor for
        the records after it).
    """
    from roughvib.results import load_result

    if isinstance(files, str | os.PathLike):
        files = [files]
    result = load_result(run_dir)
    if not result.ok:
        raise RecordError(f"{run_dir}: the run did not complete (status {result.status}); "
                          f"there is nothing to compare a record with")
    noise_rec = None
    if noise is not None:
        noise_rec = read_record(noise, column=column, units=units, scale=scale)
    out = []
    records = [read_record(f, column=column, units=units, scale=scale) for f in files]
    stems = [_stem(r.path) for r in records]
    if len(set(stems)) != len(stems):
        raise RecordError(f"two records share a file stem ({', '.join(stems)}): each "
                          f"validation is written to validation/<stem>/")
    for rec, stem in zip(records, stems, strict=True):
        v = compare_record(result, rec, signal=signal, start=start, fmax=fmax,
                           noise=noise_rec, noise_rms=noise_rms, margin_db=margin_db)
        _write(v, Path(run_dir) / VALIDATION_DIR / stem, dpi)
        out.append(v)
    return out


def read_validations(run_dir: str | os.PathLike) -> list[tuple[Path, dict]]:
    """Every validation written for a run: (folder, ``validation.json`` content), by name.

    Parameters
    ----------
    run_dir : path

    Returns
    -------
    list of (Path, dict)
        Unreadable summaries are skipped.
    """
    base = Path(run_dir) / VALIDATION_DIR
    out = []
    if base.is_dir():
        for folder in sorted(p for p in base.iterdir() if p.is_dir()):
            try:
                out.append((folder, json.loads((folder / "validation.json").read_text())))
            except (OSError, ValueError):
                continue
    return out


def velocity_exponent_of(pairs) -> dict:
    """Velocity exponents of measured and simulated levels over several validated runs.

    Parameters
    ----------
    pairs : list of (path, path)
        Run directory and record file of validations already written (:func:`validate`),
        of runs at two or more friction velocities.

    Returns
    -------
    dict
        See :func:`roughvib.analysis.validation.validation_velocity_exponent`.
    """
    summaries = []
    for run, record in pairs:
        want = _stem(str(record))
        found = [s for p, s in read_validations(run) if p.name == want]
        if not found:
            raise RecordError(f"{run}: no validation of {record} (roughvib validate)")
        summaries.append(found[0])
    return validation_velocity_exponent(summaries)


def validation_section(run_dir: str | os.PathLike) -> str | None:
    """HTML of the run report's validation section, or None if the run has none.

    One row per validation (record, signal, overall difference, bands compared, largest band
    difference, bands at the noise floor) and each validation's figure.
    """
    from roughvib.views.html import esc, figure, num, png_data_uri, table

    vals = read_validations(run_dir)
    if not vals:
        return None
    rows, figs = [], []
    for folder, s in vals:
        rows.append([folder.name, Path(str(s.get("record", ""))).name, s.get("signal", ""),
                     num(s.get("overall_difference_db"), "+.2f"),
                     num(s.get("overall_measured_db"), ".1f"),
                     num(s.get("overall_simulated_db"), ".1f"),
                     s.get("bands_compared", ""), num(s.get("max_abs_difference_db"), ".2f"),
                     "" if s.get("bands_at_noise_floor") is None
                     else s.get("bands_at_noise_floor")])
        png = folder / "validation.png"
        if png.is_file():
            figs.append(figure(png_data_uri(png.read_bytes()), alt=f"validation {folder.name}",
                               caption_html=f"<b>{esc(folder.name)}</b>: "
                                            f"{esc(s.get('summary', ''))}"))
    head = ["validation", "record", "signal", "overall difference [dB]",
            "measured [dB re 1e-6 m/s²]", "simulated [dB re 1e-6 m/s²]", "bands",
            "largest |band difference| above the noise floor [dB]", "bands at noise floor"]
    note = ("<p class='note'>difference = measured − simulated, over the bands both cover "
            "(roughvib validate; bands.csv in validation/&lt;name&gt;/ has every band).</p>")
    return table(head, rows) + note + "".join(figs)
