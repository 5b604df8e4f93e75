"""Scene illuminants as camera neutrals: `distributions` (Gaussian + hull, mixture, CCT locus) and
the camera-independent `prior` of measured scene lights (fitted by `prior_fit`, in the (mired, Duv)
plane of `mired_duv`)."""
