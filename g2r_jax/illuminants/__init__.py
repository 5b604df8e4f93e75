"""Scene illuminants as camera neutrals: `distributions` (Gaussian + hull, mixture, CCT locus)."""
