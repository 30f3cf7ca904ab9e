"""Stage 7 of the pipeline, the views: figures of a run (figures), the one HTML page builder
(html) and the reports built on it (report: run report; sweep_report), and the surface
inspection files (surface_report)."""
