"""Attack classes on what the commands read besides DNGs: side inputs (noise tables, spectral
sensitivities), chart CSVs, hostile file names, images whose headers lie about their size.

Each class mutates a good seed (written here, no data files needed) and checks, at the reader
where the file is taken in, the promises of issue 21:

- the reader returns a value that later stages can use (finite, in range), or raises the
  project's one error type for that input (`DngError`, `ChartError`) whose line starts with the
  file's name; no other exception escapes;
- the line a command would print (`g2r_jax.cli.common.error_message`) is one line of printable
  characters, at most `MAX_MESSAGE` long;
- memory stays bounded by the file's real data (images: the process's peak resident memory).

Run `python tests/input_attacks.py KIND N [SEED]` (KIND: noise-table, sensitivities, charts,
names, images, all); it prints one JSON line per kind {kind, cases, seed, findings, peak_rss_mib}.
Findings are kept in tests/fuzz_corpus/ as '<kind>_<hash>.<ext>' and replayed by test_fuzz.py.
"""

from __future__ import annotations

import hashlib
import io
import json
import random
import resource
import struct
import sys
import tempfile
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from g2r_jax.cli.common import MAX_MESSAGE, error_message  # noqa: E402
from g2r_jax.colour.charts import CHROMATIC, ChartError, read_charts  # noqa: E402
from g2r_jax.io.dng_info import DngError  # noqa: E402

CORPUS = Path(__file__).resolve().parent / "fuzz_corpus"
KINDS = ("noise-table", "sensitivities", "charts", "names", "images")
BLACK, WHITE = [64.0, 64.0, 64.0, 64.0], 1023.0
HOSTILE = ("\n", "\r", "\x1b[31m", "\x1b[2K", "\x07", "\x00", "\t", "\u202e", "\udcff", "\x7f", "\x9b")
VALUES = ("nan", "inf", "-inf", "", "abc", "1e400", "-1", "0", "1e-320", "1e308", "-0", "0x10", " 5 ", "1,5",
          "\x1b[31m1", "9" * 400)
MAX_PEAK_MIB = 1024


# ----------------------------------------------------------------------------- seeds

def noise_table_seed() -> str:
    rows = ["iso,cfa_channel_index,beta1_shot,beta2_read"]
    for iso in (100, 200, 400, 800):
        for position in range(4):
            rows.append(f"{iso},{position},{0.05 * iso / 100:.6g},{-2.5 + 0.01 * position:.6g}")
    return "\n".join(rows) + "\n"


def sensitivities_seed(kind: str) -> str:
    wavelengths = np.arange(380, 781, 5)
    curves = np.stack([np.exp(-0.5 * ((wavelengths - centre) / 35.0) ** 2) for centre in (600, 540, 460)], 1)
    if kind == "json":
        main = {str(int(w)): [round(float(v), 6) for v in row] for w, row in zip(wavelengths, curves)}
        return json.dumps({"header": {"manufacturer": "Test", "model": "Cam"},
                           "spectral_data": {"units": "relative", "data": {"main": main}}})
    return "wavelength,r,g,b\n" + "".join(f"{w},{r:.6f},{g:.6f},{b:.6f}\n" for w, (r, g, b) in zip(wavelengths, curves))


def chart_seed(rng: random.Random) -> str:
    lines = ["image,patch,r,g,b"]
    for image in range(3):
        for patch in range(1, 25):
            lines.append(f"im{image},{patch}," + ",".join(f"{rng.uniform(0.02, 0.9):.5f}" for _ in range(3)))
        lines.append(f"im{image},illuminant," + ",".join(f"{rng.uniform(0.3, 1.0):.5f}" for _ in range(3)))
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- mutations of text

def mutate_csv(text: str, rng: random.Random) -> tuple[str, str]:
    """A field replaced, a row dropped or doubled, a column dropped, units scaled, bytes flipped."""
    lines = text.splitlines()
    choice = rng.randrange(8)
    if choice <= 2:
        row = rng.randrange(len(lines))
        fields = lines[row].split(",")
        column = rng.randrange(len(fields))
        fields[column] = rng.choice(VALUES)
        lines[row] = ",".join(fields)
        return "\n".join(lines) + "\n", f"field {row + 1}:{column + 1}"
    if choice == 3 and len(lines) > 1:
        del lines[rng.randrange(1, len(lines))]
        return "\n".join(lines) + "\n", "row dropped"
    if choice == 4:
        row = rng.randrange(1, len(lines))
        lines.insert(row, lines[row])
        return "\n".join(lines) + "\n", "row doubled"
    if choice == 5:
        column = rng.randrange(len(lines[0].split(",")))
        return "\n".join(",".join(f for i, f in enumerate(line.split(",")) if i != column) for line in lines) + "\n", \
            "column dropped"
    if choice == 6:
        scale = rng.choice((1e-3, 1e3, 65535.0, 1 / 65535.0, -1.0, 0.0))
        out = [lines[0]]
        for line in lines[1:]:
            out.append(",".join(_scaled(f, scale) if i >= 2 else f for i, f in enumerate(line.split(","))))
        return "\n".join(out) + "\n", f"values x {scale:g}"
    data = bytearray(text.encode())
    for _ in range(rng.randint(1, 6)):
        data[rng.randrange(len(data))] = rng.randrange(256)
    return data.decode("utf-8", "surrogateescape"), "bytes"


def _scaled(field: str, scale: float) -> str:
    try:
        return repr(float(field) * scale)
    except ValueError:
        return field


def mutate_json(text: str, rng: random.Random) -> tuple[str, str]:
    """A node of the JSON replaced by a value of another type, deleted, or the text flipped."""
    document = json.loads(text)
    nodes = []

    def walk(node, path):
        nodes.append(path)
        if isinstance(node, dict):
            for key, value in node.items():
                walk(value, path + (key,))
        elif isinstance(node, list):
            for index, value in enumerate(node):
                walk(value, path + (index,))

    walk(document, ())
    if rng.random() < 0.2:
        data = bytearray(text.encode())
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return data.decode("utf-8", "surrogateescape"), "bytes"
    path = rng.choice(nodes)
    replacement = rng.choice(("str", "\x1b[2K" * 50, None, 0, -1, 1e308, float("nan"), [], {}, [1, 2], True,
                              "DELETE", "x" * 100000))
    if not path:
        return json.dumps(replacement if replacement != "DELETE" else None), "top level replaced"
    parent = document
    for key in path[:-1]:
        parent = parent[key]
    if replacement == "DELETE":
        del parent[path[-1]]
    else:
        parent[path[-1]] = replacement
    return json.dumps(document), f"{'.'.join(map(str, path))} -> {str(replacement)[:20]!r}"


# ----------------------------------------------------------------------------- promises

def line_problems(error: BaseException, path: Path) -> list:
    """The broken promises of the line a command prints for `error` about `path`."""
    line = error_message(error)
    problems = []
    if not all(char.isprintable() for char in line):
        problems.append(f"unprintable characters in {line[:120]!r}")
    if len(line) > MAX_MESSAGE:
        problems.append(f"a {len(line)}-character line")
    if str(path.name) not in line and path.name[:40] not in line:
        problems.append(f"does not name {path.name}: {line[:160]!r}")
    return problems


def _read_checked(path: Path, read, expected=(DngError,)) -> tuple:
    try:
        return read(path), []
    except expected as error:
        return None, line_problems(error, path)
    except Exception as error:  # noqa: BLE001 - any other exception is a finding
        return None, [f"{type(error).__name__} escaped: {str(error)[:160]}"]


def noise_table_case(rng: random.Random, work: Path) -> tuple:
    from g2r_jax.io.noise_table import read_noise_table_rows

    text, how = mutate_csv(noise_table_seed(), rng)
    path = work / "noise.csv"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    value, problems = _read_checked(path, lambda p: read_noise_table_rows(p, BLACK, WHITE))
    if value is not None:
        isos, beta1, beta2 = value
        span = WHITE - np.asarray(BLACK)
        read = (beta1 * np.asarray(BLACK) + beta2) / span**2
        if not (np.all(np.isfinite(isos)) and np.all(isos > 0) and np.all(beta1 / span > 0)
                and np.all(beta1 / span <= 1) and np.all(read >= 0) and np.all(read <= 1)):
            problems.append("accepted a table that does not fit the camera")
    return problems, how, path


def sensitivities_case(rng: random.Random, work: Path) -> tuple:
    from g2r_jax.io.sensitivities import read_sensitivities

    kind = rng.choice(("json", "csv"))
    text, how = (mutate_json if kind == "json" else mutate_csv)(sensitivities_seed(kind), rng)
    path = work / f"sensitivities.{kind}"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    value, problems = _read_checked(path, read_sensitivities)
    if value is not None and not (np.all(np.isfinite(value.values)) and np.all(value.values >= 0)
                                  and len(value.camera) <= 200 and value.camera.isprintable()):
        problems.append("accepted sensitivities that are not finite, or a camera name that is not printable")
    return problems, how, path


def charts_case(rng: random.Random, work: Path) -> tuple:
    text, how = mutate_csv(chart_seed(rng), rng)
    if rng.random() < 0.15:             # what the documented format allows: every patch nan
        lines = text.splitlines()
        text = "\n".join([lines[0]] + [(",".join(line.split(",")[:2] + ["nan"] * 3) if ",illuminant," not in line
                                        else line) for line in lines[1:]]) + "\n"
        how += ", every patch nan"
    path = work / "charts.csv"
    path.write_bytes(text.encode("utf-8", "surrogateescape"))
    charts, problems = _read_checked(path, read_charts, expected=(ChartError,))
    if charts is not None:
        ratios = charts.illuminant / charts.illuminant[:, 1:2]
        if not np.isfinite(charts.patches[:, CHROMATIC]).all(-1).any():
            problems.append("accepted charts without one measured chromatic patch")
        if not (np.all(np.isfinite(ratios)) and np.all(ratios > 0)):
            problems.append("accepted a degenerate illuminant")
    return problems, how, path


def names_case(rng: random.Random, work: Path) -> tuple:
    """A file name with control characters, undecodable bytes or great length, in an error."""
    name = "".join(rng.choice(("a", "b", "é", " ", *HOSTILE)) for _ in range(rng.randint(1, 30)))
    name = name.replace("/", "_").replace("\x00", "0") * rng.choice((1, 1, 1, 8))
    name = name[:200] + ".png"
    path = work / name
    try:
        path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(rng.randrange(256) for _ in range(rng.randint(0, 60))))
    except (OSError, ValueError):
        path = work / "fallback.png"
        path.write_bytes(b"")
    from g2r_jax.io.images import read_image

    _, problems = _read_checked(path, read_image)
    problems = [p for p in problems if not p.startswith("does not name")]       # escaped: checked below
    try:
        read_image(path)
    except DngError as error:
        from g2r_jax.cli.common import shown

        if " ".join(shown(path.name)[:40].split()) not in error_message(error):
            problems.append(f"escaped name missing from {error_message(error)[:160]!r}")
    except Exception:  # noqa: BLE001 - reported above
        pass
    return problems, f"name {name[:40]!r}", path


def _png(width: int, height: int, rows: int, depth: int = 8, colour: int = 2, interlace: int = 0) -> bytes:
    channels = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[colour]
    row_bytes = 1 + (width * channels * depth + 7) // 8
    raw = b"".join(b"\0" + bytes(row_bytes - 1) for _ in range(rows))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, interlace))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def images_case(rng: random.Random, work: Path) -> tuple:
    """Headers claiming sizes their data does not hold (PNG, JPEG, TIFF)."""
    from PIL import Image

    from g2r_jax.io.images import read_image

    kind = rng.choice(("png", "png", "jpg", "tif"))
    if kind == "png":
        width = rng.choice((1, 7, 640, 8000, 20000, 65535, 2**31 - 1))
        height = rng.choice((1, 2, 480, 8000, 30000, 2**31 - 1))
        rows = min(height, rng.choice((0, 1, 10, height)), 4_000_000 // (1 + 3 * width))   # at most 4 MB of data
        data, how = _png(width, height, rows, interlace=rng.choice((0, 0, 1))), f"png {width}x{height}, {rows} rows"
    else:
        buffer = io.BytesIO()
        Image.fromarray(np.zeros((16, 24, 3), np.uint8)).save(buffer, format="JPEG" if kind == "jpg" else "TIFF")
        data = bytearray(buffer.getvalue())
        # (a JPEG's small lie, e.g. 8000x10 from 16x24 of data, stays within the bound of one bit per block
        # and is decoded with grey fill: a known limit, see docs/pages/validation/reliability.md)
        width, height = rng.choice((8000, 40000, 65000)), rng.choice((10, 8000, 65000) if kind == "tif" else (8000, 65000))
        if kind == "jpg":
            at = data.index(b"\xff\xc0")
            data[at + 5:at + 9] = struct.pack(">HH", height, width)
        else:
            import tifffile

            with tifffile.TiffFile(io.BytesIO(bytes(data))) as tif:
                for code, value in ((256, width), (257, height)):
                    tag = tif.pages.first.tags[code]
                    if tag.dtype == 3:
                        data[tag.offset + 2:tag.offset + 4] = struct.pack("<H", 4)
                    data[tag.valueoffset:tag.valueoffset + 4] = struct.pack("<I", value)
        data, how = bytes(data), f"{kind} claiming {width}x{height}"
    path = work / f"claim.{kind}"
    path.write_bytes(data)
    complete = kind == "png" and rows == height            # the only case whose data holds its claim
    value, problems = _read_checked(path, read_image)
    if value is not None and not complete:
        problems.append(f"decoded {value[0].shape[:2]} silently from data that does not hold {height}x{width}")
    return problems, how, path


CASES = {"noise-table": noise_table_case, "sensitivities": sensitivities_case, "charts": charts_case,
         "names": names_case, "images": images_case}


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def campaign(kind: str, n: int, seed: int = 0, save_findings: bool = False) -> dict:
    """`n` cases of `kind` from `seed`: {kind, cases, seed, findings, peak_rss_mib}."""
    findings = []
    with tempfile.TemporaryDirectory(prefix="g2r_attack_") as scratch:
        for case in range(n):
            work = Path(scratch) / f"case{case}"
            work.mkdir()
            rng = random.Random(f"{kind}:{seed}:{case}")
            problems, how, path = CASES[kind](rng, work)
            if problems:
                findings.append({"case": case, "input": how, "problems": problems})
                if save_findings:
                    CORPUS.mkdir(exist_ok=True)
                    data = path.read_bytes()
                    (CORPUS / f"{kind}_{hashlib.sha256(data).hexdigest()[:10]}{path.suffix}").write_bytes(data)
    peak = peak_rss_mib()
    if kind == "images" and peak > MAX_PEAK_MIB:
        findings.append({"case": None, "input": "the whole campaign", "problems": [f"peak memory {peak:.0f} MiB"]})
    return {"kind": kind, "cases": n, "seed": seed, "findings": findings, "peak_rss_mib": round(peak)}


def replay(path: Path) -> list:
    """The broken promises of one corpus file of these classes (by its name's kind)."""
    from g2r_jax.io.images import read_image
    from g2r_jax.io.noise_table import read_noise_table_rows
    from g2r_jax.io.sensitivities import read_sensitivities

    kind = path.name.split("_", 1)[0]
    readers = {"noise-table": (lambda p: read_noise_table_rows(p, BLACK, WHITE), (DngError,)),
               "sensitivities": (read_sensitivities, (DngError,)), "charts": (read_charts, (ChartError,)),
               "images": (read_image, (DngError,))}
    read, expected = readers[kind]
    return _read_checked(path, read, expected)[1]


if __name__ == "__main__":
    kinds = KINDS if sys.argv[1] == "all" else (sys.argv[1],)
    count, first_seed = int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 0
    for name in kinds:
        result = campaign(name, count, first_seed, save_findings=True)
        print(json.dumps({**result, "findings": result["findings"][:20], "n_findings": len(result["findings"])}),
              flush=True)
