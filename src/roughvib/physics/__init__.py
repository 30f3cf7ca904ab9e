"""Stage 1 of the pipeline, the physics: plate modes (plate), the friction law (friction) and
the rough surface (surface: profile, interpolant, statistical contact)."""
