"""The work-precision figure: point labels of runs with about equal cost and error stay legible."""

import pandas as pd

from roughvib.views.work_precision import label_boxes, plot_work_precision


def _table() -> pd.DataFrame:
    rows = []
    # a cluster: five runs of one method within 5 % in cost and error, as adaptive-modal's
    # coarse rungs and presets are on the paper scene; and a second method crossing it
    for i, (rtol, preset) in enumerate([(1e-3, ""), (1e-4, ""), (1e-4, "draft"),
                                        (1e-5, "standard"), (1e-5, "")]):
        rows.append(dict(method="adaptive-modal", setting=rtol, setting_name="rtol",
                         preset=preset, wall_time=3.6 + 0.05 * i, error=0.07 + 0.002 * i))
    for i, step in enumerate([2e-5, 1e-5, 5e-6]):
        rows.append(dict(method="exact-modal", setting=step, setting_name="step [s]",
                         preset="", wall_time=3.5 + 0.1 * i, error=0.075 - 0.001 * i))
    t = pd.DataFrame(rows)
    t["status"] = "success"
    for col in ("plate_band_db", "block_band_db", "velocity_rel_rms", "event_dt_max",
                "energy_rel_residual", "contract_ratio"):
        t[col] = t["error"]
    return t


def test_point_labels_do_not_overlap(tmp_path):
    fig = plot_work_precision(_table(), tmp_path / "wp.png", "test", contract={"band_db": 1.0})
    assert (tmp_path / "wp.png").stat().st_size > 10_000
    boxes = label_boxes(fig)
    assert sum(len(b) for b in boxes) == 6 * 8  # every run labelled in every panel
    for panel in boxes:
        for i, a in enumerate(panel):
            for b in panel[:i]:
                assert not a.overlaps(b), (a, b)


def test_labels_overlap_without_spreading(tmp_path, monkeypatch):
    """The check above can fail: the same labels left at their first offset do overlap."""
    from roughvib.views import work_precision as wp

    monkeypatch.setattr(wp, "_spread_labels", lambda fig, axes: fig.draw_without_rendering())
    fig = wp.plot_work_precision(_table(), tmp_path / "wp.png", "test")
    assert any(a.overlaps(b) for panel in label_boxes(fig)
               for i, a in enumerate(panel) for b in panel[:i])
