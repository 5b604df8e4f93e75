"""The DNG metadata g2r_jax reads and writes, as one plain dataclass.

Tag numbers and meanings: Adobe, *Digital Negative (DNG) Specification* 1.6 (2020), chapter 4.
Reading fills it from a real file (`read_dng_info`), writing turns it into TIFF tags
(`write_dng`); the numeric core never sees it (profiles and metadata are pytrees).
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numpy as np

CFA_COLOUR_NAMES = ("R", "G", "B")


@dataclasses.dataclass
class DngInfo:
    """Everything g2r_jax needs from (or writes to) one DNG.

    Matrices are numpy float64 arrays, row-major 3x3; `None` means the tag is absent.
    `cfa_pattern` lists the colour index (0=R, 1=G, 2=B) of the 2x2 tile in row-major order,
    e.g. RGGB -> (0, 1, 1, 2). `black_level` is per tile position (4 values, DN);
    `noise_profile` is the DNG NoiseProfile as (S, O) pairs per colour plane, in normalised
    units: variance = S * x + O with x in [0, 1] after black subtraction and scaling.
    """

    path: str = ""
    width: int = 0
    height: int = 0
    is_cfa: bool = True                       # False for LinearRaw (PhotometricInterpretation 34892)
    photometric: int = 32803
    bits_per_sample: int = 16
    cfa_pattern: tuple = (0, 1, 1, 2)
    black_level: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4))
    white_level: float = 65535.0
    unique_camera_model: str = ""
    make: str = ""
    model: str = ""
    dng_version: tuple = (1, 4, 0, 0)
    calibration_illuminants: tuple = ()       # EXIF LightSource codes, one per ColorMatrix
    color_matrices: tuple = ()                # XYZ -> camera, one per calibration illuminant
    camera_calibrations: tuple = ()           # same length as color_matrices, or empty
    forward_matrices: tuple = ()              # same length as color_matrices, or empty
    illuminant_data: tuple = ()               # per matrix: white (x, y) of a code-255 illuminant or None; or empty
    analog_balance: Optional[np.ndarray] = None
    as_shot_neutral: Optional[np.ndarray] = None
    as_shot_white_xy: Optional[np.ndarray] = None
    baseline_exposure: float = 0.0
    noise_profile: Optional[np.ndarray] = None   # shape (planes, 2) or (1, 2)
    iso: Optional[float] = None
    exposure_time: Optional[float] = None
    active_area: Optional[tuple] = None       # (top, left, bottom, right)
    default_crop_origin: Optional[tuple] = None
    default_crop_size: Optional[tuple] = None
    opcode_lists: dict = dataclasses.field(default_factory=dict)  # {"OpcodeList1": bytes, ...}
    warnings: list = dataclasses.field(default_factory=list)      # non-fatal problems found on read
    cfa_repeat_dim: tuple = (2, 2)            # CFARepeatPatternDim (rows, cols); () for LinearRaw
    pixel_data_problem: Optional[str] = None  # set on read when the raw pixel data is missing/short
    compression: int = 1                      # raw IFD's Compression (TIFF 259): 1, 7, 34892, 52546, ...
    linearization_table: Optional[np.ndarray] = None  # LinearizationTable (50712), applied by LibRaw

    def cfa_string(self) -> str:
        """The 2x2 pattern as letters, e.g. 'RGGB'."""
        return "".join(CFA_COLOUR_NAMES[c] for c in self.cfa_pattern)


class DngError(ValueError):
    """A DNG (or image) g2r_jax cannot use; the message names the file and the problem."""

    MAX_PROBLEM = 240   # messages stay one short line, whatever a damaged file holds

    def __init__(self, path, problem: str):
        self.path = str(path)
        problem = " ".join(str(problem).split())
        if len(problem) > self.MAX_PROBLEM:
            problem = problem[: self.MAX_PROBLEM - 3] + "..."
        self.problem = problem
        super().__init__(f"{path}: {problem}")
