"""The downstream check as a library call: does a network trained on g2r_jax RAW of your CG images
work on your camera? `run_check` reads and vets the inputs (`downstream.inputs`), trains the
illuminant estimators of `downstream.illuminant.experiment` on every row's training set and tests them on
the real DNGs (labelled by their AsShotNeutral), compares the CG content with the real files
(`downstream.illuminant.content`), optionally runs the denoising check on a burst
(`downstream.denoising.burst_check`), and returns a `report.Report`; `report.write_report` writes it.
"""

from __future__ import annotations

from typing import Callable, Optional, Sequence

from g2r_jax.downstream import report
from g2r_jax.downstream.illuminant import content, experiment, reporting
from g2r_jax.downstream.inputs import Inputs, read_inputs
from g2r_jax.io.image_headers import DEFAULT_MAX_PIXELS

DEFAULT_ESTIMATORS = ("cnn", "histogram")
TASKS = ("colour", "isp")      # on the real DNGs: illuminant estimation, the neural ISP (`downstream.isp.task`)
# The ISP task is asked for, not run by default: it trains a UNet per row, fold and seed, which
# costs more than the rest of the colour check (docs/pages/validation/downstream_isp.md).
DEFAULT_TASKS = ("colour",)


def default_rows(profile_given: bool, content_rows: bool = False) -> tuple:
    """The experiment's rows: every default row ('fitted', the product as `g2r-fit-profile` makes
    it, with its controls), 'shipped' only when a profile was given (a fitted profile has no light
    of its own to test), and with `content_rows` UPI on the product's adapted CG content
    (`experiment.CONTENT_ROWS`, `downstream.illuminant.content_rows`). Other rows (`experiment.ROWS`) are
    passed to `run_check(rows=...)`."""
    rows = tuple(r for r in experiment.DEFAULT_ROWS if profile_given or r != "shipped")
    return rows + (experiment.CONTENT_ROWS if content_rows else ())


def camera_profile(profile, inputs: Inputs):
    """`profile` (a SensorProfile, a shipped name or a file) loaded, or one fitted from the real
    DNGs' tags as `g2r-fit-profile` would (from the burst's frames without real DNGs), without
    its content model: the colour check fits that per fold (`downstream.illuminant.content_rows`),
    `with_files_content` adds the one of all the files."""
    from g2r_jax.io.dng_read import read_dng_info
    from g2r_jax.profile.fitting import fit_profile
    from g2r_jax.profile.schema import SensorProfile, load_profile

    if isinstance(profile, SensorProfile):
        return profile
    if profile is not None:
        return load_profile(profile)
    if inputs.real is not None:
        return fit_profile([read_dng_info(path) for path in inputs.real.files], name=inputs.real.name or "measured",
                           illuminant_model="prior")
    return fit_profile(list(inputs.burst.infos), name="burst", illuminant_model="prior")


def with_files_content(sensor, inputs: Inputs):
    """A fitted `sensor` with the content model `g2r-fit-profile` fits to the same files (the real
    DNGs, else the burst's frames): the product the burst check measures."""
    from g2r_jax.io.dng_read import read_dng_info
    from g2r_jax.profile.fitting import content_model_of_dngs
    from g2r_jax.profile.schema import replace

    infos = [read_dng_info(path) for path in inputs.real.files] if inputs.real is not None else list(inputs.burst.infos)
    model, _, _ = content_model_of_dngs(infos, sensor.colour)
    return sensor if model is None else replace(sensor, content=model)


def _product_views(views, real, profile):
    """CG views as the product sees them, for the comparison of contents: through the profile's
    content model (applied in the simulation when it carries one), else through the one
    `g2r-fit-profile` fits to the real files (`product.FITTED`); as they are when the files'
    cast cannot be fitted."""
    from g2r_jax.downstream.base import product

    if getattr(profile, "content", None) is not None:
        return views
    try:
        model = product.candidate_model(product.FITTED, real.images, real.illuminants, views, profile)
    except ValueError:
        return views
    return product.adapted_views(model, views, 5)


def _colour_check(inputs: Inputs, profile, *, rows, estimators, seeds, n, folds, say, workers=None,
                  cache=None) -> tuple:
    """(ExperimentResult, JSON part, sentences, markdown lines) of the colour check."""
    from g2r_jax.downstream.base.product import fitted_illuminants
    from g2r_jax.downstream.base.training_sets import cg_views, g2r_set, real_to_linear_srgb

    real = inputs.real
    result = experiment.illuminant_experiment(real, profile, inputs.cg, rows=rows, estimators=estimators,
                                              seeds=seeds, n=n, folds=folds, progress=say, workers=workers,
                                              cache=cache)
    fitted = fitted_illuminants(profile, real.illuminants)
    synthetic = g2r_set(_product_views(cg_views(inputs.cg, min(n, 300), 0), real, profile), fitted, 0)
    round_trip = g2r_set(real_to_linear_srgb(real.images, real.illuminants, profile),
                         experiment.without_content(profile), 0, neutrals=real.illuminants)
    differences = content.compare(synthetic, (real.images, real.illuminants), round_trip)
    document = {**result.to_dict(), "decomposition": {e: reporting.decomposition(result, e) for e in estimators},
                "content": differences}
    sentences = [reporting.sentence(result, e, differences) for e in estimators]
    notes = [*(f"- {note}" for note in result.notes), ""] if result.notes else []
    markdown = [reporting.table(result), "", *notes, "## What differs in the CG content", "",
                reporting.content_table(differences), ""]
    return result, document, sentences, markdown


def _curve_check(inputs: Inputs, profile, result, *, counts, estimators, seeds, n, folds, say, workers=None,
                 cache=None):
    """The labelled-files curve of the colour check (`labelled_curve.run_curve`)."""
    from g2r_jax.downstream.illuminant.labelled_curve import run_curve

    return run_curve(inputs.real, profile, inputs.cg, result, counts=counts, estimators=estimators, seeds=seeds, n=n,
                     folds=folds, workers=workers, progress=say, cache=cache)


def _isp_rows(profile_given: bool) -> tuple:
    from g2r_jax.downstream.isp import task as isp_task

    return tuple(r for r in isp_task.ROWS if r in isp_task.DEFAULT_ROWS or (profile_given and r == "shipped"))


def _isp_check(inputs: Inputs, profile, *, profile_given: bool, seeds, folds, say, cache=None) -> tuple:
    """(IspResult, JSON part, sentence, markdown lines) of the neural-ISP task on the real DNGs
    (`downstream.isp.task.run_isp_task`, its own number of synthetic pairs)."""
    from g2r_jax.downstream.isp import task as isp_task

    result = isp_task.run_isp_task(inputs.real, profile, inputs.cg, rows=_isp_rows(profile_given), seeds=seeds,
                                   folds=folds, progress=say, cache=cache)
    lines = ["## Neural ISP (RAW -> sRGB)", "", result.sentence(), "", result.table(), "",
             "Where the colour error lies (each test image's ΔE2000 left after its best white balance and its "
             "best 3 x 3 colour correction, `downstream.isp.error_parts`):", "", result.parts_table(), "",
             *(f"- {note}" for note in result.notes), "",
             "Predicted against target on a few real test files: `isp.png`.", ""]
    return result, result.to_dict(), result.sentence(), lines


def _burst_contents(inputs: Inputs) -> tuple:
    return ("cg", "scene") if inputs.cg_paths else ("scene",)


def _plan(progress, inputs: Inputs, *, tasks, rows, estimators, seeds: int, folds: int, choose: bool,
          profile_given: bool, curve=()) -> None:
    """Tell `progress` (a `downstream.base.progress.Progress`) every training the check will run, so
    that its time left covers the whole check."""
    from g2r_jax.downstream.base.progress import plan
    from g2r_jax.downstream.denoising import burst_check
    from g2r_jax.downstream.isp import task as isp_task

    units = 0
    if inputs.real is not None and "colour" in tasks:
        from g2r_jax.downstream.illuminant.labelled_curve import trainings as curve_trainings

        units += experiment.trainings(rows, estimators, range(seeds), folds)
        units += curve_trainings(curve, len(inputs.real.images) * (folds - 1) // folds, estimators, range(seeds), folds)
    if inputs.real is not None and "isp" in tasks:
        units += isp_task.trainings(_isp_rows(profile_given), range(seeds), folds)
    if inputs.burst is not None:
        units += burst_check.trainings(inputs.burst.n, burst_check.ROWS, _burst_contents(inputs), range(seeds),
                                       choose=choose)
    plan(progress, units)


def _burst_check(inputs: Inputs, profile, *, seeds, steps, say, cache=None) -> tuple:
    """(DenoisingResult, JSON part, sentence, markdown lines) of the burst's denoising check
    (`burst_check.run_burst_check`)."""
    from g2r_jax.downstream.denoising import burst_check

    contents = _burst_contents(inputs)
    result = burst_check.run_burst_check(inputs.burst, profile, inputs.cg_paths, contents=contents, seeds=seeds,
                                         steps=steps, progress=say, cache=cache)
    document = {"psnr": {f"{r}/{c}": v for (r, c), v in result.psnr.items()}, "noisy_psnr": result.noisy_psnr,
                "peak": result.peak, "steps": result.steps, "step_curve": list(result.step_curve),
                "cg_levels": result.cg_levels, "noise": result.noise, "frames": list(result.frames), "iso": result.iso}
    return result, document, result.sentence(), ["## Denoising on the burst", "", result.summary(), ""]


def _inputs_document(inputs: Inputs) -> dict:
    real = inputs.real
    return {"camera": real.name if real is not None else "", "label": real.label if real is not None else None,
            "files": list(real.files) if real is not None else [], "cg_images": [str(p) for p in inputs.cg_paths],
            "burst_frames": list(inputs.burst.names) if inputs.burst is not None else [],
            "notes": list(inputs.notes), "problems": [{"path": p, "reason": r} for p, r in inputs.problems]}


def run_check(measured: Sequence = (), cg: Sequence = (), *, burst=None, profile=None,
              estimators: Sequence[str] = DEFAULT_ESTIMATORS, rows: Optional[Sequence[str]] = None, seeds: int = 2,
              n: int = 600, folds: int = 3, denoiser_steps: Optional[int] = None, max_pixels: Optional[int] = DEFAULT_MAX_PIXELS,
              tasks: Sequence[str] = DEFAULT_TASKS, dry_run: bool = False, progress: Optional[Callable[[str], None]] = None, workers: Optional[int] = None,
              on_problem: Optional[Callable[[str, str], None]] = None, curve: Sequence[int] = (),
              cache=None) -> report.Report:
    """Run the downstream check (see the module docstring).

    **Arguments:** `measured`: folders or files of the camera's real DNGs (the colour check;
    needs `cg`; may be empty with a `burst`); `cg`: folders or files of CG images; `burst`: a
    folder of DNGs of one static scene (the denoising check) or None; `profile`: the camera's
    `SensorProfile`, a shipped name or a profile file (None: fitted from the DNGs' tags);
    `estimators`: some of `estimators.ESTIMATORS`; `rows`: the colour check's training sets
    (`experiment.ROWS`; None: `default_rows`); `seeds`: repetitions with new synthetic sets;
    `n`: synthetic training images per set; `folds`: cross-validation folds of the real files;
    `denoiser_steps`: Adam steps per denoiser (None: chosen on a validation split of the burst); `max_pixels`: the largest CG image read;
    `tasks`: what the real DNGs are used for, some of `TASKS` ('colour': the illuminant
    estimators; 'isp': the neural ISP, `downstream.isp.task`); `dry_run`: read and vet every input and
    the profile, train nothing; `progress`: a callable
    taking one line of text, or a `downstream.base.progress.Progress` (a bar of the check's trainings
    with the time left); `workers`: rows of the colour check trained side by side
    (`experiment.illuminant_experiment`); `on_problem(path, reason)`: called as each input is left out;
    `curve`: numbers of labelled real files for the augmentation curve (`downstream.illuminant.labelled_curve`:
    real alone and real + g2r_jax at each; needs the rows 'real' and 'real_plus_fitted'); `cache`:
    a `downstream.base.cache.DownstreamCache` of finished trainings of the colour check, the ISP task and
    the burst check (None: off; the command's default is the user's cache folder, `--no-cache` off).

    **Returns:** a `report.Report` (its `status` is the command's exit status). **Raises:**
    `DngError` naming the folder when a check cannot run on its inputs, ValueError for options
    that do not fit together.
    """
    if not measured and burst is None:
        raise ValueError("nothing to check: give real DNGs (measured) with CG images, or a burst, or both")
    if measured and not cg:
        raise ValueError("the colour check needs CG images (cg) beside the real DNGs")
    if not tasks or any(t not in TASKS for t in tasks):
        raise ValueError(f"tasks {', '.join(map(repr, tasks)) or '(none)'}: expected some of {', '.join(TASKS)}")
    unknown = [r for r in rows or () if r not in experiment.ROWS]
    if unknown:
        raise ValueError(f"unknown rows {', '.join(map(repr, unknown))}; expected some of {', '.join(experiment.ROWS)}")
    say = progress or (lambda line: None)
    inputs = read_inputs(measured, cg, burst, folds=folds, max_pixels=max_pixels, on_problem=on_problem,
                         progress=progress)
    for note in inputs.notes:
        say(note)
    sensor = camera_profile(profile, inputs)
    document, sentences = _inputs_document(inputs), []
    title = inputs.real.name if inputs.real is not None else (inputs.burst.names[0] if inputs.burst else "")
    markdown = [f"# Downstream check: {title}", ""]
    if inputs.real is not None:
        markdown += [f"Real files: {len(inputs.real.images)}; labels: {inputs.real.label}.", ""]
    if dry_run:
        sentences.append(_dry_run_sentence(inputs))
        return report.Report(camera=document["camera"], sentences=sentences, document={**document, "dry_run": True},
                             markdown="\n".join(markdown + sentences + [""]), problems=inputs.problems,
                             notes=inputs.notes)
    result = denoised = None
    body = []
    rows = default_rows(profile is not None) if rows is None else tuple(rows)
    _plan(progress, inputs, tasks=tasks, rows=rows, estimators=estimators, seeds=seeds, folds=folds,
          choose=denoiser_steps is None, profile_given=profile is not None, curve=curve)
    isp_result = curve_result = None
    if inputs.real is not None and "colour" in tasks:
        result, part, said, lines = _colour_check(inputs, sensor, rows=rows, estimators=tuple(estimators),
                                                  seeds=tuple(range(seeds)), n=n, folds=folds, say=say,
                                                  workers=workers, cache=cache)
        document.update(part)
        sentences += said
        body += lines
        if curve:
            curve_result = _curve_check(inputs, sensor, result, counts=curve, estimators=tuple(estimators),
                                        seeds=tuple(range(seeds)), n=n, folds=folds, say=say, workers=workers,
                                        cache=cache)
            document["augmentation_curve"] = curve_result.to_dict()
            body += ["## Labelled real files: what adding g2r_jax RAW is worth", "", curve_result.table(), "",
                     "The curve: `augmentation.png`.", ""]
    if inputs.real is not None and "isp" in tasks:
        isp_result, part, said, lines = _isp_check(inputs, sensor, profile_given=profile is not None,
                                                   seeds=tuple(range(seeds)), folds=folds, say=say, cache=cache)
        document["isp"] = part
        sentences.append(said)
        body += lines
    if inputs.burst is not None:
        product = sensor if profile is not None else with_files_content(sensor, inputs)
        denoised, part, said, lines = _burst_check(inputs, product, seeds=tuple(range(seeds)), steps=denoiser_steps,
                                                   say=say, cache=cache)
        document["denoising"] = part
        sentences.append(said)
        body += lines
    if cache is not None and cache.enabled and (result is not None or isp_result is not None or denoised is not None):
        document["cache"] = {"folder": str(cache.folder), "reused": cache.hits, "trained": cache.misses}
        body += [f"- {cache.summary()}", *(f"- {note}" for note in cache.notes), ""]
    markdown += [*sentences, "", *body]
    return report.Report(camera=document["camera"], sentences=sentences, document=document,
                         markdown="\n".join(markdown), result=result, denoising=denoised, isp=isp_result,
                         curve=curve_result, problems=inputs.problems, notes=inputs.notes)


def _dry_run_sentence(inputs: Inputs) -> str:
    parts = []
    if inputs.real is not None:
        from g2r_jax.downstream.base.real_sets import distinct_lights

        parts.append(f"{len(inputs.real.images)} real DNG(s) of {inputs.real.name!r} under "
                     f"{len(distinct_lights(inputs.real.illuminants))} distinct light(s)")
    if inputs.cg:
        parts.append(f"{len(inputs.cg)} CG image(s)")
    if inputs.burst is not None:
        parts.append(f"a burst of {inputs.burst.n} frames")
    return (f"dry run: would use {', '.join(parts)}; {len(inputs.problems)} input(s) left out; nothing trained.")
