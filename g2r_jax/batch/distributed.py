"""Many devices and many machines: a batch sharded over the local devices, folders on Ray.

- `unprocess_sharded`: `unprocess_batch` with the batch axis split over every local device (a
  `jax.sharding.Mesh` over the devices, `NamedSharding` of the images and mosaics along the
  batch axis; XLA partitions the element-wise pixel work, each device its own images).
  `unprocess_batch` computes each image the same way whatever batch it is in, so the result is
  bit for bit the unsharded one.
- `convert_files_ray`: `g2r-convert --engine ray`. The sorted inputs are cut into chunks, each
  chunk a Ray task (Ray schedules, retries and places them on the cluster's nodes) running the
  local batch driver `convert_files`; the driver collects the records and writes one manifest.
  Keys derive from (seed, file name) and `unprocess_batch` does not depend on batching, so every
  DNG has the same bytes as with the local engine. Ray is optional: `pip install -e .[ray]`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from g2r_jax.pipeline import unprocess_batch

BATCH_AXIS = "batch"


def batch_mesh(devices=None) -> Mesh:
    """A one-axis mesh ('batch') over `devices` (default: all local devices)."""
    devices = jax.local_devices() if devices is None else list(devices)
    return Mesh(np.asarray(devices), (BATCH_AXIS,))


def unprocess_sharded(keys, images, profile, *, neutral=None, devices=None, **options):
    """`unprocess_batch(keys, images, profile, neutral=neutral, **options)`, the batch split
    over the local devices.

    **Arguments:** `keys` (B, ...) and `images` (B, H, W, 3) as for `unprocess_batch`;
    `neutral`: None or (B, 3); `devices`: the devices to use (default `jax.local_devices()`);
    other keyword options (transfer, noise, effects, iso, ...) as `unprocess_batch`. A batch
    that does not divide evenly is padded with copies of its last image, dropped again.

    **Returns:** `(mosaics (B, H, W), metadata)`: the mosaics sharded over the devices along
    the batch axis, the (small) metadata replicated.
    """
    mesh = batch_mesh(devices)
    count = len(mesh.devices.flat)
    size = images.shape[0]
    padded = math.ceil(size / count) * count

    def pad(array):
        if array is None or padded == size:
            return array
        array = jnp.asarray(array)
        return jnp.concatenate([array, jnp.repeat(array[-1:], padded - size, axis=0)])

    keys, images, neutral = pad(keys), pad(images), pad(neutral)
    images = jax.device_put(images, NamedSharding(mesh, PartitionSpec(BATCH_AXIS)))
    if neutral is not None:
        neutral = jnp.asarray(neutral, jnp.float32)
    settings = tuple(sorted(options.items()))
    try:
        program = _sharded_program(mesh, settings)
    except TypeError:    # an unhashable option (an array): compile without the cache
        program = _sharded_program.__wrapped__(mesh, settings)
    mosaics, metadata = program(keys, images, profile, neutral)
    if padded != size:
        mosaics, metadata = mosaics[:size], {k: v[:size] for k, v in metadata.items()}
    return mosaics, metadata


@functools.lru_cache(maxsize=32)
def _sharded_program(mesh, options):
    """`unprocess_batch` jitted with the images and mosaics split along the batch axis.

    The per-image conditions (a few 3x3 matrices per image, from the replicated keys) are cheap
    and computed on every device; the pixels, element-wise per image, are partitioned by XLA's
    SPMD partitioner along the batch axis, with no communication."""
    batch, replicated = NamedSharding(mesh, PartitionSpec(BATCH_AXIS)), NamedSharding(mesh, PartitionSpec())

    def program(keys, images, profile, neutral):
        return unprocess_batch(keys, images, profile, neutral=neutral, **dict(options))

    return jax.jit(program, in_shardings=(replicated, batch, replicated, replicated),
                   out_shardings=(batch, replicated))


# ----------------------------------------------------------------------------- Ray


def _require_ray():
    try:
        import ray
    except ImportError:
        raise ImportError("the Ray engine needs Ray: pip install 'g2r_jax[ray]' (or pip install 'ray[data]')") from None
    return ray


def _convert_chunk(files, profile, out_dir, neutrals, options, names=None):
    """One Ray task: the local batch driver on a chunk of files, without the manifest (`profile`:
    the driver's `SensorProfile`, which Ray hands over from its object store)."""
    from g2r_jax.batch.conversion import convert_files

    result = convert_files(files, profile, out_dir, neutrals=neutrals, options=options,
                           write_manifest=False, names=names)
    return result.records, result.errors


def convert_files_ray(inputs, profile, out_dir, *, neutrals=None, options=None, on_error=None,
                      files_per_task: int | None = None, ray_remote_args: dict | None = None):
    """`convert_files` on a Ray cluster: the same DNGs, byte for byte, and one manifest.

    **Arguments:** `inputs`: image paths (in the order rows of `neutrals` apply); `profile`: a
    `SensorProfile`, or a shipped profile name or JSON path loaded here; either way put once in
    Ray's object store and shared by the tasks (a profile edited in memory, e.g. its content
    model turned off, converts as it is); `out_dir`: must be reachable
    from every node (a shared filesystem on a multi-machine cluster); `neutrals`: optional
    (N, 3); `options`: `ConvertOptions`; `on_error`: called with each error line;
    `files_per_task`: chunk size (default: a few batches, enough chunks to keep every CPU
    busy); `ray_remote_args`: passed to `.options()` of each task (e.g. `{"num_gpus": 1}`).
    Connects to the running cluster (`ray.init()` honours RAY_ADDRESS) or starts a local one.

    **Returns:** `ConvertResult` with the records in input order.
    """
    ray = _require_ray()
    from g2r_jax.batch.conversion import (ConvertOptions, ConvertResult, output_names, refused_outputs,
                                          write_manifest_file)

    options = options or ConvertOptions()
    chunk_options = dataclasses.replace(options, progress=False)
    given_inputs, given_out_dir = [Path(p) for p in inputs], Path(out_dir)
    inputs = [p.absolute() for p in given_inputs]      # tasks may run in another working directory
    out_dir = given_out_dir.absolute()
    out_dir.mkdir(parents=True, exist_ok=True)
    errors = []

    def report(line):
        errors.append(line)
        if on_error:
            on_error(line)

    # Output names and their collisions are a property of the whole run, not of a chunk: decided
    # here, as locally.
    names = output_names(given_inputs)
    refused = refused_outputs(given_inputs, names, out_dir, options)
    keep = []
    for index in range(len(given_inputs)):
        if index in refused:
            report(str(refused[index]))
        else:
            keep.append(index)

    if not ray.is_initialized():
        ray.init()
    if files_per_task is None:
        workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        files_per_task = max(options.batch_size, math.ceil(len(keep) / (4 * workers) / options.batch_size) * options.batch_size)
    task = ray.remote(_convert_chunk).options(**(ray_remote_args or {"num_cpus": 1}))
    if isinstance(profile, (str, Path)):
        from g2r_jax.profile.schema import load_profile

        profile = load_profile(profile)
    profile = ray.put(profile)    # once, not once per task
    pending = {}
    for start in range(0, len(keep), files_per_task):
        chunk = keep[start:start + files_per_task]
        rows = None if neutrals is None else np.asarray(neutrals)[chunk]
        pending[task.remote([inputs[i] for i in chunk], profile, out_dir, rows, chunk_options,
                            [names[i] for i in chunk])] = start

    progress = None
    if options.progress:
        from tqdm import tqdm
        progress = tqdm(total=len(keep), unit="image", desc="g2r-convert (ray)")
    by_output = {}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        pending.pop(done[0])
        records, chunk_errors = ray.get(done[0])
        for record in records:
            by_output[record["input"]] = record
        for line in chunk_errors:
            report(line)
        if progress:
            progress.update(len(records) + len(chunk_errors))
    if progress:
        progress.close()
    ordered = []
    for i in keep:
        record = by_output.get(str(inputs[i]))
        if record is not None:   # the manifest names files as they were given, like the local engine
            ordered.append(dict(record, input=str(given_inputs[i])))
    write_manifest_file(out_dir, ordered)
    return ConvertResult(records=ordered, errors=errors)
