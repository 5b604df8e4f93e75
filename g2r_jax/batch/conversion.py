"""Batch conversion of CG image files into DNGs of the profiled camera.

The driver around `unprocess`: decodes files on worker threads ahead of the compute, runs one
jitted `unprocess_batch` per batch of same-sized images (the last batch padded, so shapes and
compiled code are reused; a batch is dispatched asynchronously and its results handed to the
writers only once the next batch is queued), and writes DNGs atomically on worker threads.
Memory stays bounded by the images in flight (loading window, two batches, writing window)
whatever the folder size. A bad file is reported and the batch goes on. Every image's PRNG key
derives from (seed, file name), so the same seed gives the same bytes whatever the batch order
or batch size.
"""

from __future__ import annotations

import collections
import concurrent.futures as futures
import dataclasses
import os
import zlib
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from g2r_jax.io.atomic import OutputError, atomic_write_bytes
from g2r_jax.io.dng_info import DngError, DngInfo
from g2r_jax.io.image_headers import DEFAULT_MAX_PIXELS
from g2r_jax.io.output_folder import MANIFEST_NAME, OutputFolder, manifest_bytes
from g2r_jax.batch.program_store import stored_program
from g2r_jax.pipeline import unprocess_batch
from g2r_jax.profile.dng_tags import dng_info_for, lens_shading_for
from g2r_jax.runtime.host_arrays import device_array
from g2r_jax.sensor.effects import changes_nothing

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")


@dataclasses.dataclass
class ConvertOptions:
    """Options of a conversion run (all keyword-only in `convert_files`)."""

    seed: int = 0
    iso: float | None = None
    noise: bool = True
    effects: bool = True
    transfer: str = "auto"        # 'auto': sRGB for PNG/JPEG/TIFF, linear for EXR
    recipe: str = "dng"
    colour: str = "matrix"        # colour stage: 'matrix', 'spectral', 'spectral-jakob2019'
    batch_size: int = 4
    workers: int = 2
    crop_odd: bool = False
    lens_shading: bool = False    # divide by the camera's lens-shading gain map and write its opcode
    compression: str = "none"     # DNG pixels: 'none' or 'ljpeg' (lossless JPEG tiles, `g2r_jax.io.dng_write`)
    pairs: bool = False           # also write each task's pair beside the DNG (`g2r_jax.batch.pairs`)
    developed: bool = False       # with `pairs`: also the reference developer's target of the clean DNG
    progress: bool = True
    max_pixels: int | None = DEFAULT_MAX_PIXELS        # per image; larger images are refused by name
    max_batch_pixels: int | None = 2 * DEFAULT_MAX_PIXELS   # per compiled call; fewer images per batch above it


@dataclasses.dataclass
class ConvertResult:
    """What a run did: one manifest record per converted file, one error line per failure."""

    records: list
    errors: list
    notes: list = dataclasses.field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors


def file_key(seed: int, name: str):
    """PRNG key of one input: folded from the seed and a CRC-32 of the file name."""
    return jax.random.fold_in(jax.random.PRNGKey(seed), _name_hash(name))


def _name_hash(name: str) -> int:
    return zlib.crc32(name.encode()) & 0x7FFFFFFF


@jax.jit
def _folded_keys(base, hashes):
    return jax.vmap(lambda value: jax.random.fold_in(base, value))(hashes)


def file_keys(seed: int, names) -> jax.Array:
    """`file_key(seed, name)` of every name, stacked, folded in one compiled program (each eager
    JAX operation costs a command's start-up a compilation-cache read)."""
    return _folded_keys(jax.random.PRNGKey(seed), np.asarray([_name_hash(name) for name in names], np.uint32))


def _transfer_for(path: Path, transfer: str) -> str:
    if transfer != "auto":
        return transfer
    return "linear" if path.suffix.lower() == ".exr" else "srgb"


def _load(path: Path, crop_odd: bool, max_pixels=DEFAULT_MAX_PIXELS):
    from g2r_jax.io import images

    array = images.read_image_uint8(path, max_pixels=max_pixels)
    if array is None:
        array, _ = images.read_image(path, max_pixels=max_pixels)
    height, width = array.shape[:2]
    if height % 2 or width % 2:
        if not crop_odd:
            raise DngError(path, f"odd image size {width}x{height}: a 2x2 CFA needs even sizes "
                                 f"(use --crop-odd to drop the last row/column)")
        array = array[: height - height % 2, : width - width % 2]
    if array.shape[0] < 2 or array.shape[1] < 2:
        raise DngError(path, f"image too small ({width}x{height})")
    return np.ascontiguousarray(array)


BUCKET_STEP = 64          # bucket sides are multiples of this
MAX_PADDING_FACTOR = 4.0  # an image shares a bucket of at most this many times its own area


def _probe_size(path: Path):
    """(height, width) from the file header (no decoding), None when unknown."""
    try:
        from PIL import Image

        with Image.open(path) as image:
            width, height = image.size
        return height, width
    except Exception:  # noqa: BLE001 - unknown sizes get an exact-size bucket when decoded
        return None


def _predicted_group(path: Path, transfer: str, buckets, max_pixels):
    """The batch group (bucket, dtype, transfer) `path` will fall in once decoded, read from its
    header; None when that is not certain before decoding (TIFF, EXR, unreadable headers) or the
    header's claim is not credible (over the pixel budget, more than the data can hold): a program
    compiled ahead for a file that is then refused would only make the user wait."""
    from g2r_jax.io import image_headers
    from g2r_jax.io.images import PLAUSIBLE_PNG_RATIO

    suffix = path.suffix.lower()
    try:
        if suffix == ".png":
            width, height, depth, _, claimed, present = image_headers.png_claim(path)
            image_headers.check_pixel_budget(path, width, height, max_pixels)
            if claimed > PLAUSIBLE_PNG_RATIO * max(present, 1):
                return None
            dtype = np.dtype(np.uint8 if depth <= 8 else np.float32)    # 16 bits are decoded as float
        elif suffix in (".jpg", ".jpeg"):
            width, height = image_headers.check_jpeg_complete(path, max_pixels)
            dtype = np.dtype(np.uint8)
        else:
            return None
    except Exception:  # noqa: BLE001 - the decoder names the problem; nothing is prepared
        return None
    size = (height - height % 2, width - width % 2)
    return bucket_for(size, buckets), dtype.str, _transfer_for(path, transfer)


def plan_buckets(sizes):
    """Padded shapes for a set of (h, w): the largest sizes first, each reusing an existing
    bucket that holds it at most `MAX_PADDING_FACTOR` times its area, else opening one rounded
    up to `BUCKET_STEP`. A compiled program per bucket, not per size (padding costs element-wise
    work; a compilation costs seconds)."""
    buckets = []
    for height, width in sorted(set(sizes), key=lambda s: (-s[0] * s[1], s)):
        if not any(h >= height and w >= width and h * w <= MAX_PADDING_FACTOR * height * width for h, w in buckets):
            buckets.append((-(-height // BUCKET_STEP) * BUCKET_STEP, -(-width // BUCKET_STEP) * BUCKET_STEP))
    return buckets


def bucket_for(shape, buckets):
    """The smallest planned bucket holding `shape` within the padding factor, else `shape`."""
    height, width = shape
    fits = [(h * w, (h, w)) for h, w in buckets
            if h >= height and w >= width and h * w <= MAX_PADDING_FACTOR * height * width]
    return min(fits)[1] if fits else (height, width)


_COMPILED = {}


def _batched_unprocess(options: ConvertOptions, transfer: str, with_neutral: bool, effects: bool):
    """One jitted `unprocess_batch` per option set (jax caches the compiled code per shape).

    `unprocess_batch` gives every image the same bytes whatever batch it falls in, so outputs do
    not depend on the batch size, on padding, or on which engine or chunk converted a file.
    `effects`: whether the sensor effects are rendered (False for a profile whose effects change
    nothing, `sensor.effects.changes_nothing`: the same bytes, a fifth of the CPU time)."""
    signature = (options.noise, effects, options.recipe, transfer, with_neutral, options.iso is not None,
                 options.lens_shading, options.colour) + (("pairs",) if options.pairs else ())

    if signature not in _COMPILED:
        def batch(keys, images, profile, neutrals, iso, lens_gain, valid_shapes):
            return unprocess_batch(keys, images, profile, transfer=transfer, noise=options.noise, valid_shapes=valid_shapes,
                                   effects=effects, recipe=options.recipe, colour=options.colour,
                                   neutral=neutrals if with_neutral else None,
                                   iso=iso if options.iso is not None else None,
                                   lens_gain=lens_gain if options.lens_shading else None,
                                   return_clean=options.pairs, return_scene=options.pairs)

        # traced once per option set and shape, then kept on disk for the next process (program_store)
        _COMPILED[signature] = stored_program(repr(signature), jax.jit(batch))
    return _COMPILED[signature]


def output_names(inputs) -> list[str]:
    """Each input's DNG path under the output folder, without `.dng`: its path relative to the
    deepest folder holding all inputs, with `/` separators. Files of one folder keep their stems
    (`0001`); files of several folders keep their folders (`sceneA/0001`, `sceneB/0001`)."""
    folders = [os.path.abspath(Path(p).parent) for p in inputs]
    if not folders:
        return []
    root = os.path.commonpath(folders)
    return [Path(os.path.relpath(os.path.abspath(p), root)).with_suffix("").as_posix() for p in inputs]


def colliding_names(names) -> set[str]:
    """Output names claimed by more than one input (same name, another extension)."""
    return {name for name, count in collections.Counter(names).items() if count > 1}


def collision_error(path, name: str) -> DngError:
    return DngError(path, f"another input would also be written to {name}.dng (same name, another extension); "
                          "rename one")


def _pair_files(path, name: str, options: ConvertOptions) -> dict:
    from g2r_jax.batch.pairs import pair_outputs

    linear = _transfer_for(Path(path), options.transfer) == "linear"
    return pair_outputs(name, linear=linear, developed=options.developed)


def refused_outputs(inputs, names, out_dir, options: ConvertOptions) -> dict:
    """{input index: DngError} for the inputs refused before anything is written because one of
    their outputs would collide: two inputs with one output name (`colliding_names`), and with
    `options.pairs` any pair file claimed twice or naming an input (`batch.pairs.output_conflicts`).
    A property of the whole run (the Ray engine decides it before splitting the files)."""
    duplicates = colliding_names(names)
    refused = {i: collision_error(path, names[i]) for i, path in enumerate(inputs) if names[i] in duplicates}
    if options.pairs:
        from g2r_jax.batch.pairs import output_conflicts

        conflicts = output_conflicts(inputs, names, out_dir, lambda i: {
            "dng": names[i] + ".dng", **_pair_files(inputs[i], names[i], options)})
        for index, problem in conflicts.items():
            refused.setdefault(index, DngError(inputs[index], problem))
    return refused


def _manifest_record(path, output, metadata, seed, content: str | None = None, pair: dict | None = None):
    from g2r_jax.batch.pairs import illuminant_label, pair_record

    record = {"input": str(path), "output": str(output),
              "neutral": [round(float(v), 8) for v in np.asarray(metadata["neutral"])],
              "illuminant_rgb": illuminant_label(metadata["neutral"]),
              "xy": [round(float(v), 8) for v in np.asarray(metadata["xy"])],
              "cct": round(float(metadata["cct"]), 3), "iso": round(float(metadata["iso"]), 3),
              "exposure_gain": round(float(metadata["exposure_gain"]), 6), "seed": seed}
    if content is not None:   # the content model the scene went through (`g2r_jax.content.describe`)
        record["content_model"] = content
    if pair is not None:      # the task pairs' files (`g2r_jax.batch.pairs`), relative to the folder
        record["pair"] = pair_record(pair)
    return record


def applied_content(profile) -> str | None:
    """What the conversion does to the scene before the camera: the profile's content model when
    it applies by default (conversion follows the profile's block), else None."""
    model = getattr(profile, "content", None)
    if model is None or not model.apply_by_default:
        return None
    from g2r_jax.content import describe

    return describe(model)


def convert_files(inputs, profile, out_dir, *, neutrals=None, options: ConvertOptions | None = None,
                  on_error=None, write_manifest: bool = True, names=None) -> ConvertResult:
    """Convert image files into DNGs `out_dir/<name>.dng` and write `out_dir/manifest.jsonl`.

    **Arguments:** `inputs`: image paths (already expanded, in the order rows of `neutrals`
    apply); `profile`: a SensorProfile; `out_dir`; `neutrals`: optional (N, 3) camera neutrals,
    row i for input i; `options`: `ConvertOptions`; `on_error`: called with each error line;
    `write_manifest`: False leaves the manifest to the caller (a chunk of a distributed run);
    `names`: each input's output path under `out_dir` without `.dng` (default `output_names`:
    the stem for files of one folder, `folder/stem` for files of several). A file's random key
    derives from the seed and its name with the input's extension (`0001.png`, `sceneA/0001.png`);
    the manifest names outputs relative to `out_dir`.

    The folder is opened as an `OutputFolder` (locked against a second writer, temporaries of a
    killed run removed, manifest rebuilt from what is there) and each DNG's record is appended as
    soon as the file is in place, so that an interrupted run leaves a manifest listing exactly the
    DNGs written. A fault of the folder itself (disk full, permissions) stops the batch with
    `OutputError` naming the file. Images above `options.max_pixels` are refused by name.

    **Returns:** `ConvertResult` (records in input order, error lines, notes about the folder).
    """
    if not write_manifest:
        return _convert_files(None, inputs, profile, out_dir, neutrals=neutrals, options=options, on_error=on_error,
                              names=names)
    with OutputFolder(out_dir) as folder:
        return _convert_files(folder, inputs, profile, out_dir, neutrals=neutrals, options=options, on_error=on_error,
                              names=names)


def _folder_notes(folder) -> list:
    """Lines about what an earlier run left in the folder."""
    notes = []
    if folder.removed_temporaries:
        notes.append(f"{folder.path}: removed {folder.removed_temporaries} temporary file(s) left by an interrupted run")
    if folder.unlisted:
        shown = ", ".join(folder.unlisted[:3]) + (", ..." if len(folder.unlisted) > 3 else "")
        notes.append(f"{folder.path}: {len(folder.unlisted)} DNG(s) not listed in its manifest ({shown}): "
                     "written by another program, or by a run that was killed")
    return notes


def _convert_files(folder, inputs, profile, out_dir, *, neutrals=None, options: ConvertOptions | None = None,
                   on_error=None, names=None) -> ConvertResult:
    from g2r_jax.io.dng_write import COMPRESSIONS

    options = options or ConvertOptions()
    if options.compression not in COMPRESSIONS:
        raise ValueError(f"unknown DNG compression {options.compression!r} (choose from {', '.join(COMPRESSIONS)})")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    if options.lens_shading:
        lens_shading_for(profile, 2, 2)  # fail early, before any file, if the profile has no opcodes
    run = _BatchRun(folder, [Path(p) for p in inputs], profile, out_dir, neutrals, options, on_error, names)
    with futures.ThreadPoolExecutor(max(1, options.workers)) as pool:
        run.convert(pool)
    if run.progress:
        run.progress.close()
    ordered = [run.records[i] for i in sorted(run.records)]
    if folder is None:
        return ConvertResult(records=ordered, errors=run.errors)
    rewritten = {folder.key(r) for r in ordered}
    folder.rewrite([r for r in folder.records if folder.key(r) not in rewritten] + ordered)
    return ConvertResult(records=ordered, errors=run.errors, notes=_folder_notes(folder))


class _BatchRun:
    """One conversion batch: files are decoded on a thread pool ahead of the compute (a window of
    2 x batch size), gathered into groups of one padded shape (`plan_buckets`), run through one
    compiled call per group, and handed to writer threads one batch later, so that decoding,
    computing and writing overlap; records and error lines are kept per input index."""

    def __init__(self, folder, inputs, profile, out_dir, neutrals, options, on_error, names):
        self.folder, self.inputs, self.profile, self.out_dir = folder, inputs, profile, out_dir
        self.neutrals, self.options, self.on_error = neutrals, options, on_error
        self.names = output_names(inputs) if names is None else [str(n) for n in names]
        self.refused = refused_outputs(inputs, self.names, out_dir, options)
        self.records, self.errors, self.lens = {}, [], {}
        self.progress = None
        if options.progress:
            from tqdm import tqdm
            self.progress = tqdm(total=len(inputs), unit="image", desc="g2r-convert")
        self.render_effects = options.effects and not changes_nothing(profile.effects)
        # Images are zero-padded to a few bucket shapes (bit-identical output: `valid_shapes`),
        # except with per-size lens gains or a noise correlation kernel, which see the padding.
        self.bucketing = not options.lens_shading and getattr(profile.noise, "correlation_kernel", None) is None
        sizes = [size for size in map(_probe_size, inputs) if size] if self.bucketing else []
        self.buckets = plan_buckets([(h - h % 2, w - w % 2) for h, w in sizes])
        self.window = max(2 * options.batch_size, options.workers)
        self.pending = {}    # batch group (bucket, dtype, transfer) -> [(index, image)] waiting for partners
        self.preparing = []  # the ahead-of-time compilation of the first group, awaited before the first call
        self.in_flight = []  # batches dispatched to the device, handed to the writers one batch later
        self.writing = []
        self.pool = None

    def report(self, line):
        self.errors.append(line)
        if self.on_error:
            self.on_error(line)

    def lens_for(self, height, width):
        if (height, width) not in self.lens:
            self.lens[(height, width)] = lens_shading_for(self.profile, height, width)
        return self.lens[(height, width)]

    def pair_of(self, index) -> dict:
        """{role: relative path} of the pair files input `index` gets (`batch.pairs.pair_outputs`)."""
        return _pair_files(self.inputs[index], self.names[index], self.options)

    def write_pair(self, index, mosaic, clean, scene, metadata, opcodes) -> dict:
        """Write the pair files of input `index` (each atomically, before its DNG); returns the
        manifest's {role: path}. A clean mosaic equal to the noisy one is not written twice: the
        pair's 'clean' names the DNG itself."""
        from g2r_jax.batch import pairs
        from g2r_jax.io.dng_write import write_dng_bytes

        name, pair = self.names[index], self.pair_of(index)
        pairs.checked_size(name, scene, mosaic.shape)
        clean_bytes = None
        if np.array_equal(clean, mosaic):
            pair["clean"] = f"{name}.dng"
        else:
            info = pairs.clean_dng_info(self.profile, metadata, *clean.shape, opcode_list2=opcodes)
            clean_bytes = write_dng_bytes(np.asarray(clean), info, where=self.out_dir / pair["clean"],
                                          compression=self.options.compression)
            atomic_write_bytes(self.out_dir / pair["clean"], clean_bytes)
        atomic_write_bytes(self.out_dir / pair["scene"], pairs.scene_png_bytes(scene))
        if "scene_linear" in pair:
            atomic_write_bytes(self.out_dir / pair["scene_linear"], pairs.scene_exr_bytes(scene))
        if "developed" in pair:
            if clean_bytes is None:
                info = pairs.clean_dng_info(self.profile, metadata, *clean.shape, opcode_list2=opcodes)
                clean_bytes = write_dng_bytes(np.asarray(clean), info, where=self.out_dir / pair["clean"])
            atomic_write_bytes(self.out_dir / pair["developed"],
                               pairs.developed_png_bytes(clean_bytes, str(self.out_dir / pair["clean"])))
        return pair

    def write(self, index, path, mosaic, metadata, clean=None, scene=None):
        """Write one DNG (atomically; its manifest record appended once it is in place), and its
        pair files first when `clean` and `scene` are given."""
        from g2r_jax.io.dng_write import write_dng_bytes

        options, name = self.options, self.names[index]
        output = self.out_dir / f"{name}.dng"
        try:
            output.parent.mkdir(parents=True, exist_ok=True)
            opcodes = self.lens_for(*mosaic.shape)[1] if options.lens_shading else None
            pair = None if clean is None else self.write_pair(index, mosaic, clean, scene, metadata, opcodes)
            info = dng_info_for(self.profile, metadata, mosaic.shape[0], mosaic.shape[1], noise=options.noise,
                                opcode_list2=opcodes)
            record = _manifest_record(path, f"{name}.dng", metadata, options.seed, applied_content(self.profile), pair)
            folder = self.folder
            atomic_write_bytes(output, write_dng_bytes(np.asarray(mosaic), info, where=output,
                                                       compression=options.compression),
                               after_rename=(lambda: folder.append(record, output)) if folder else None)
        except DngError:
            raise                # OutputError included: the folder failed, not this input
        except Exception as error:  # noqa: BLE001 - name the input whatever went wrong
            raise DngError(path, f"writing {output} failed: {type(error).__name__}: {error}") from error
        return index, record

    def collect(self, future):
        _collect(future, self.inputs, self.records, self.report, self.progress)

    def hand_over(self, batch, *outputs):
        """Hand a finished batch to the writers: `outputs` the program's (mosaics, [clean mosaics,
        scenes,] metadata)."""
        arrays = [np.asarray(a) for a in outputs[:-1]]   # waits for this batch only: the next one is queued
        metadata = {k: np.asarray(v) for k, v in outputs[-1].items()}
        for j, (index, image) in enumerate(batch):
            height, width = image.shape[:2]
            mosaic, *pair = (a[j, :height, :width] for a in arrays)
            self.writing.append(self.pool.submit(self.write, index, self.inputs[index], mosaic,
                                                 {k: v[j] for k, v in metadata.items()}, *pair))
        while len(self.writing) > self.window:    # bounded memory: writers keep up or the compute waits
            self.collect(self.writing.pop(0))

    def group_of(self, path, image):
        shape = bucket_for(image.shape[:2], self.buckets) if self.bucketing else image.shape[:2]
        return shape, image.dtype.str, _transfer_for(path, self.options.transfer)

    def capacity(self, shape):
        """Images per compiled call of this shape: the batch size, fewer above the batch pixel
        budget or when there are fewer inputs (one file is not padded to a batch of four)."""
        size = min(self.options.batch_size, len(self.inputs))
        if self.options.max_batch_pixels is None:
            return max(1, size)
        return max(1, min(size, self.options.max_batch_pixels // max(1, shape[0] * shape[1])))

    def program(self, transfer):
        return _batched_unprocess(self.options, transfer, self.neutrals is not None, self.render_effects)

    def prepare(self, group):
        """Compile (or load) the program of a batch group without running it."""
        shape, dtype, transfer = group
        size, spec = self.capacity(shape), jax.ShapeDtypeStruct
        keys = jax.eval_shape(lambda: file_keys(0, [""] * size))
        arguments = (keys, spec((size,) + tuple(shape) + (3,), np.dtype(dtype)),
                     self.profile, spec((size, 3), jnp.float32), spec((), jnp.float32), spec((), jnp.float32),
                     spec((size, 2), jnp.int32))
        self.program(transfer).prepare(*arguments)

    def flush(self, group):
        """Run the pending images of `group` as one padded batch (asynchronously)."""
        batch = self.pending.pop(group, [])
        if not batch:
            return
        while self.preparing:             # its failure, if any, shows again in the call below
            ahead = self.preparing.pop()
            if ahead is not None:
                ahead.exception()
        shape, _, transfer = group
        count, size = len(batch), self.capacity(shape)
        padded = batch + [batch[-1]] * (size - count) if count < size else batch
        self.in_flight.append((batch,) + tuple(self._run_batch(padded, shape, transfer)))
        if len(self.in_flight) > 1:
            self.hand_over(*self.in_flight.pop(0))

    def _run_batch(self, padded, shape, transfer):
        """(mosaics, metadata) of one padded batch, dispatched without waiting for the result."""
        options, neutrals = self.options, self.neutrals
        # arrays made with numpy and copied (device_array): jnp constructors would each compile
        keys = file_keys(options.seed, [self.names[i] + self.inputs[i].suffix for i, _ in padded])
        stacked = np.zeros((len(padded),) + tuple(shape) + padded[0][1].shape[2:], padded[0][1].dtype)
        for j, (_, image) in enumerate(padded):
            stacked[j, :image.shape[0], :image.shape[1]] = image
        images = device_array(stacked)
        valid_shapes = device_array([image.shape[:2] for _, image in padded], np.int32)
        neutral_rows = device_array(np.stack([neutrals[i] for i, _ in padded]) if neutrals is not None
                                    else np.ones((len(padded), 3)), np.float32)
        iso = device_array(options.iso if options.iso is not None else 0.0, np.float32)
        lens_gain = device_array(self.lens_for(images.shape[1], images.shape[2])[0] if options.lens_shading
                                 else 1.0, np.float32)
        return self.program(transfer)(keys, images, self.profile, neutral_rows, iso, lens_gain, valid_shapes)

    def load(self, index):
        """The decoded image of input `index`, or None after reporting why it cannot be used."""
        path = self.inputs[index]
        try:
            if index in self.refused:
                raise self.refused[index]
            return self.loading.pop(index).result()
        except Exception as error:  # noqa: BLE001 - every per-file failure is reported, the batch goes on
            self.loading.pop(index, None)
            self.report(str(error) if isinstance(error, DngError) else f"{path}: {type(error).__name__}: {error}")
            if self.progress:
                self.progress.update(1)
            return None

    def submit_load(self, index):
        self.loading[index] = self.pool.submit(_load, self.inputs[index], self.options.crop_odd,
                                               self.options.max_pixels)

    def convert(self, pool):
        """The whole batch on `pool` (decoding and writing threads)."""
        options, inputs = self.options, self.inputs
        self.pool, self.loading = pool, {}
        for i in range(min(self.window, len(inputs))):
            self.submit_load(i)
        next_to_load = len(self.loading)
        # the first file's program is compiled (or loaded) on a thread while the first files are decoded
        first = (_predicted_group(inputs[0], options.transfer, self.buckets, options.max_pixels)
                 if self.bucketing and inputs else None)
        preparer = futures.ThreadPoolExecutor(1) if first else None
        self.preparing.append(preparer.submit(self.prepare, first) if first else None)
        if first:     # the keys' programs are read from the compilation cache while the first file decodes
            file_keys(options.seed, [""] * self.capacity(first[0]))
        for index in range(len(inputs)):
            image = self.load(index)
            if next_to_load < len(inputs):
                self.submit_load(next_to_load)
                next_to_load += 1
            if image is None:
                continue
            group = self.group_of(inputs[index], image)
            self.pending.setdefault(group, []).append((index, image))
            if len(self.pending[group]) >= self.capacity(group[0]):
                self.flush(group)
            for done in [w for w in self.writing if w.done()]:
                self.writing.remove(done)
                self.collect(done)
        for group in list(self.pending):
            self.flush(group)
        while self.in_flight:
            self.hand_over(*self.in_flight.pop(0))
        for done in self.writing:
            self.collect(done)
        if preparer is not None:
            preparer.shutdown(wait=False)


def write_manifest_file(out_dir, records) -> None:
    """`out_dir/manifest.jsonl`: one JSON record per converted file, in input order (written even
    when empty, unlike `OutputFolder.rewrite`)."""
    atomic_write_bytes(Path(out_dir) / MANIFEST_NAME, manifest_bytes(records))


def _collect(future, inputs, records, report, progress):
    try:
        index, record = future.result()
        records[index] = record
    except OutputError:
        raise                    # the folder itself failed (disk full, permissions): stop the batch
    except Exception as error:  # noqa: BLE001
        report(str(error) if isinstance(error, DngError) else f"{type(error).__name__}: {error}")
    if progress:
        progress.update(1)
