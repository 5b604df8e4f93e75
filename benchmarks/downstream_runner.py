"""The runner the per-camera downstream benchmarks share (`downstream_nus.py`, `downstream_isp_nus.py`):
their common arguments, the loop over cameras that resumes from a run's own JSON, the JSON and
markdown rewritten (atomically) after each camera, and the merging of runs for `--summary`.

A script keeps what is its own: its rows, how to run one camera, how to store one camera's result
in the JSON and its tables. It hands those to `run_cameras` as a `CameraBenchmark`.

The JSON of a run is {..the script's own fields (`header`).., "cameras": {key: entry}}: a key is a
camera (or a camera and a number of labelled files, "Canon600D@10"), an entry what the script
stores for it. An entry, or each part of it (`nesting`), is a result: a dict whose lists ("rows",
"estimators", ...) name what it holds and whose dicts ("summary", "errors", ...) are keyed by row
("fitted/cnn", "fitted/psnr"). `merge_runs` merges runs at that level, so two runs of different
rows of the same camera give the union of their rows, a later run's value winning for a row both
hold.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Optional

__all__ = ["CameraBenchmark", "add_arguments", "merge_results", "merge_runs", "merged_order", "read_cameras",
           "read_runs", "mixed_sources", "run_cameras", "write_outputs"]


def say(message: str) -> None:
    """A progress line on stderr (the tables go to stdout)."""
    print(f"  {message}", file=sys.stderr, flush=True)


def add_arguments(parser, cameras: Iterable[str], seeds: int = 3) -> None:
    """The arguments the per-camera scripts share: --cameras, --seeds, --json, --markdown, --summary."""
    parser.add_argument("--cameras", default=",".join(cameras), help="comma-separated cameras (default: all)")
    parser.add_argument("--seeds", type=int, default=seeds, help="seeds 0 .. N-1 of each training")
    parser.add_argument("--json", type=Path, help="results, rewritten after each camera; a camera already in it "
                                                  "(from a stopped run with the same file) is not run again")
    parser.add_argument("--markdown", type=Path, help="the tables, rewritten after each camera")
    parser.add_argument("--summary", help="comma-separated JSON files of earlier runs: print their tables, run nothing")


@dataclasses.dataclass(frozen=True)
class CameraBenchmark:
    """What a script gives the runner.

    `run(job)` -> the result of one camera (a module-level function when cameras run in several
    processes); `entry(result)` -> its JSON entry under "cameras"; `camera_lines(key, result)` ->
    the markdown block of a camera run now; `kept_lines(key, entry)` -> that of a camera kept from
    the JSON; `closing_lines(entries, seconds)` -> the markdown after the cameras (the tables of
    every entry so far); `header(seconds)` -> the JSON's fields before "cameras"; `indent` of the
    JSON; `is_done(entry)`: whether an entry of an earlier JSON counts as done (else it runs again)."""

    run: Callable[[Any], Any]
    entry: Callable[[Any], dict]
    camera_lines: Callable[[str, Any], list]
    kept_lines: Callable[[str, dict], list]
    closing_lines: Callable[[dict, float], list]
    header: Callable[[float], dict]
    indent: Optional[int] = None
    is_done: Callable[[dict], bool] = lambda entry: True


def run_cameras(benchmark: CameraBenchmark, jobs: dict, *, json_path: Optional[Path] = None,
                markdown_path: Optional[Path] = None, processes: int = 1) -> dict:
    """Run `benchmark.run(job)` for each (key, job) of `jobs` whose key the JSON at `json_path`
    does not hold yet, in the order of `jobs`, `processes` at a time; after each, print its block
    and rewrite the JSON and markdown (every entry of the JSON kept, the new ones added), then
    print the closing tables and write both a last time. **Returns:** the entries ({key: entry})."""
    start = time.perf_counter()
    entries = {key: entry for key, entry in read_cameras(json_path).items() if benchmark.is_done(entry)}
    todo = {key: job for key, job in jobs.items() if key not in entries}
    lines = []
    finished = _results(benchmark.run, list(todo.values()), processes)
    for key in jobs:
        if key in todo:
            result = next(finished)
            entries[key] = benchmark.entry(result)
            block = benchmark.camera_lines(key, result)
        else:
            say(f"{key}: kept from {json_path}")
            block = benchmark.kept_lines(key, entries[key])
        print("\n".join(block), flush=True)
        lines += block
        if key in todo:
            seconds = time.perf_counter() - start
            write_outputs(benchmark, entries, lines + benchmark.closing_lines(entries, seconds), seconds,
                          json_path, markdown_path)
    seconds = time.perf_counter() - start
    closing = benchmark.closing_lines(entries, seconds)
    print("\n".join(closing), flush=True)
    write_outputs(benchmark, entries, lines + closing, seconds, json_path, markdown_path)
    return entries


def _results(run: Callable, jobs: list, processes: int) -> Iterator:
    """The results of `run` on `jobs`, in their order, as each finishes (`processes` > 1: in a
    pool of that many spawned processes). A process that ran a camera drops its compiled programs
    when they crowd the kernel's mapping limit (`g2r_jax.runtime.mapping_limit`)."""
    run = functools.partial(_run_and_release, run)
    if processes <= 1 or len(jobs) <= 1:
        yield from map(run, jobs)
        return
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(processes) as pool:
        yield from pool.imap(run, jobs)


def _run_and_release(run: Callable, job):
    from g2r_jax.runtime.mapping_limit import release_if_crowded

    result = run(job)
    release_if_crowded()
    return result


def write_outputs(benchmark: CameraBenchmark, entries: dict, lines: list, seconds: float,
                  json_path: Optional[Path], markdown_path: Optional[Path]) -> None:
    """Write the markdown `lines` and the JSON of `entries`, each atomically (a run stopped while
    writing leaves the last complete file to resume from); either path may be None."""
    from g2r_jax.io.atomic import atomic_write_bytes

    if markdown_path:
        markdown_path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(markdown_path, ("\n".join(lines) + "\n").encode())
    if json_path:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        document = {**benchmark.header(seconds), "cameras": entries}
        atomic_write_bytes(json_path, json.dumps(document, indent=benchmark.indent).encode())


def read_document(path, unread: str = "left out") -> dict:
    """A run's JSON file as a dict ({} when there is none, or when it cannot be read: then a line
    says so, ending with `unread`, what follows from it)."""
    if not path or not Path(path).is_file():
        return {}
    try:
        document = json.loads(Path(path).read_text())
        if not isinstance(document.get("cameras", {}), dict):
            raise ValueError("its 'cameras' is not an object")
        return document
    except (OSError, ValueError, AttributeError) as error:
        say(f"{path}: not read ({error}); {unread}")
        return {}


def read_cameras(path) -> dict:
    """The entries ({key: entry}) of a run's JSON file to resume from, {} when there is none."""
    return dict(read_document(path, "every camera runs").get("cameras", {}))


def read_runs(paths: Iterable, nesting: int = 1, is_done: Callable[[dict], bool] = lambda entry: True,
              say: Callable[[str], None] = lambda line: print(line, file=sys.stderr)) -> tuple:
    """The entries of several runs' JSON files merged (`merge_runs`; entries not `is_done` left out)
    and the sum of their seconds; `say` gets a line for each row whose cameras come from different
    files (`mixed_sources`). **Returns:** (entries, seconds)."""
    paths = list(paths)
    documents = [read_document(path) for path in paths]
    seconds = sum(float(document.get("seconds", 0.0)) for document in documents)
    runs = [{key: entry for key, entry in document.get("cameras", {}).items() if is_done(entry)}
            for document in documents]
    for line in mixed_sources(runs, [str(p) for p in paths], nesting):
        say(line)
    return merge_runs(runs, nesting), seconds


def _row_sources(runs, names, nesting: int) -> dict:
    """{(part, row): {camera key: the last file holding it}} (part: the inner key with `nesting` 2,
    e.g. the ISP's "10", else "")."""
    sources = {}
    for run, name in zip(runs, names):
        for key, entry in run.items():
            parts = entry.items() if nesting > 1 and isinstance(entry, dict) else [("", entry)]
            for part, result in parts:
                for row in (result.get("rows", []) if isinstance(result, dict) else []):
                    sources.setdefault((part, str(row)), {})[key] = name
    return sources


def mixed_sources(runs, names, nesting: int = 1) -> list:
    """Lines naming each row (and part) whose cameras come from different files: a later file that
    holds a row for some cameras wins for those, and the others keep an earlier file's (perhaps of
    other code), which a merged table would not show."""
    lines = []
    for (part, row), by_camera in _row_sources(runs, names, nesting).items():
        files = {name: [] for name in names}
        for key, name in by_camera.items():
            files[name].append(key)
        files = {name: keys for name, keys in files.items() if keys}
        if len(files) > 1:
            where = "; ".join(f"{', '.join(sorted(keys))} from {name}" for name, keys in files.items())
            lines.append(f"note: row {row}{f' ({part})' if part else ''} merges files: {where}")
    return lines


def merge_runs(runs: Iterable[dict], nesting: int = 1) -> dict:
    """Merge the entries ({key: entry}) of several runs, in order. A key in one run only keeps its
    entry; for a key in several, the results (`nesting` 1: the entries; 2: the values of each entry,
    e.g. the ISP's {"all": result, "10": result}) are merged by `merge_results`, later winning."""
    merged = {}
    for run in runs:
        for key, entry in run.items():
            if key not in merged:
                merged[key] = entry
            elif nesting > 1:
                merged[key] = merge_runs([merged[key], entry], nesting - 1)
            else:
                merged[key] = merge_results(merged[key], entry)
    return merged


def merge_results(earlier: dict, later: dict) -> dict:
    """One result of two runs: each list the union of both (`merged_order`: "rows", "estimators",
    ...), each dict the union with the later's values for the
    keys both hold ("summary", "errors", ... keyed by row), anything else the later's."""
    merged = dict(earlier)
    for field, value in later.items():
        old = merged.get(field)
        if isinstance(old, list) and isinstance(value, list):
            merged[field] = merged_order(old, value)
        elif isinstance(old, dict) and isinstance(value, dict):
            merged[field] = {**old, **value}
        else:
            merged[field] = value
    return merged


def merged_order(*sequences: Iterable) -> list:
    """The items of the sequences, each once, in an order that keeps each sequence's: a later
    sequence's new item goes right after the item it follows there (["real", "fitted"] and
    ["real", "upi", "fitted"] give ["real", "upi", "fitted"]). Items need not be hashable."""
    out = []
    for sequence in sequences:
        position = 0
        for item in sequence:
            if item in out:
                position = out.index(item) + 1
            else:
                out.insert(position, item)
                position += 1
    return out
