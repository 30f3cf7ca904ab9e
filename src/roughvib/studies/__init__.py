"""Stage 8 of the pipeline, the studies: many runs and what they show together, the
work-precision study (compare) and parameter sweeps on Dask (sweep)."""
