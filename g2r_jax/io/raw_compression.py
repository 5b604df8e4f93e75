"""Which raw-data compressions g2r_jax can decode, from the Compression tag (TIFF 6.0 tag 259).

Codes: 1 uncompressed, 7 lossless JPEG (ITU T.81 Annex H; DNG spec ch. 4 'Compression'),
8 Deflate (DNG 1.4, floating-point data), 34892 lossy JPEG (DNG 1.4), 52546 JPEG XL (DNG 1.7),
9 VC-5 (SMPTE ST 2073, used by GoPro's GPR files). Pixels are decoded by LibRaw (rawpy); whether
its build has the lossy-JPEG and Deflate codecs is read from `rawpy.flags`. Tags of a file whose
pixels cannot be decoded are still read and used (profile fitting needs tags only).
"""

from __future__ import annotations

from typing import Optional

COMPRESSION_NAMES = {
    1: "uncompressed", 7: "lossless JPEG", 8: "Deflate", 9: "VC-5 (GoPro GPR)",
    34892: "lossy JPEG", 52546: "JPEG XL (DNG 1.7)",
}
_ALWAYS_DECODED = (1, 7)
_CODEC_FLAG = {8: "DNGDEFLATECODEC", 34892: "DNGLOSSYCODEC"}


def compression_name(code: int) -> str:
    return COMPRESSION_NAMES.get(int(code), f"unknown compression {int(code)}")


def _libraw_flags() -> dict:
    try:
        import rawpy

        return dict(getattr(rawpy, "flags", None) or {})
    except Exception:  # noqa: BLE001 - without rawpy nothing beyond the baseline codecs is known
        return {}


def undecodable_reason(code: int) -> Optional[str]:
    """None when LibRaw decodes raw data of this Compression code; else the one-line reason."""
    code = int(code)
    if code in _ALWAYS_DECODED:
        return None
    flag = _CODEC_FLAG.get(code)
    if flag is not None and _libraw_flags().get(flag):
        return None
    return (f"raw data is {compression_name(code)} compressed (Compression {code}), which this LibRaw "
            "cannot decode: pixels unavailable, tags still used")
