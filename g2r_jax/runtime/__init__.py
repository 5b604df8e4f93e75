"""Runtime knobs: the persistent compile cache, XLA flags (CPU vector width, deterministic GPU
ops) and float64 where a solve needs it (`x64`)."""
