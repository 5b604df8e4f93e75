"""Diagnoses of the neural-ISP benchmark's rows (issue 49 part 3), not product settings: what the
gap between the control row (real scenes made RAW again, `real_profile_light`) and real training
is made of, and whether the synthetic pairs' exposure matters. Each is an option of
`downstream_isp_nus.py`, applied before the run by replacing one method of the task's row
builder (`task._RowSets`), as `--content-part` does for the content model.

- `--control-light own`: the control's scenes under their own measured lights instead of lights
  drawn from the fitted model;
- `--control-exposure own`: each control pair's level (`top_levels`) set to its own real pair's;
- `--metered-exposure`: every g2r_jax pair's level set to a level drawn at random from the real
  training pairs' levels (the way a camera's auto-exposure places its files);
- `--joint-scenes`: the 'fitted' row's views each take the cast of one training file's scene
  (`content.fitting.scene_cast_targets`) and that file's own light, drawn together, instead of
  the files' median cast under lights drawn apart from it;
- `--texture real|noise`: every g2r_jax view (and UPI's) times the texture of a real training
  thumbnail, or a Gaussian draw of their texture's covariance (`textured`);
- `--cast-only`: the g2r_jax rows take a 'scenes' model's median cast even with the texture;
- `--texture-after`: the texture drawn after the content model instead of before it (with
  `--cast-only`: the texture's first form, the median cast then the texture);
- `--texture-scale S`: the product's texture (`content.texture`) with its amplitude times S;
- `--real-fill mean`: the NUS thumbnails' missing pixels (0: masked chart, saturated pixels)
  written as the image's mean colour instead of white (`fill_missing`), in the real DNGs of both
  training and test; the masks stay as they were.
"""

from __future__ import annotations

import numpy as np


def top_levels(packed: np.ndarray, masks=None) -> np.ndarray:
    """(N,) the 99th percentile of each packed input's brightest channel per tile, over the tiles
    whose target pixels are measured (`masks` (N, 2h, 2w), None: every tile)."""
    top = np.asarray(packed).max(-1).reshape(len(packed), -1)
    if masks is None:
        return np.quantile(top, 0.99, axis=1)
    kept = np.asarray(masks)[:, ::2, ::2].reshape(len(packed), -1)
    return np.array([np.quantile(t[k] if k.any() else t, 0.99) for t, k in zip(top, kept)])


def fill_missing(images: np.ndarray) -> np.ndarray:
    """Thumbnails (N, h, w, 3) with their missing pixels (0 in every channel) set to the mean
    colour of the image's other pixels."""
    images = np.array(images, np.float32)
    for image in images:
        missing = np.all(image <= 0, axis=-1)
        if missing.any() and not missing.all():
            image[missing] = image[~missing].mean(0)
    return images


def _scaled_to(levels, make, views, masks):
    """The pairs of `make(views)` again with each view scaled so that its pair's level is `levels`."""
    packed, _ = first = make(views)
    gains = np.asarray(levels) / np.maximum(top_levels(packed, masks), 1e-4)
    return make(views * gains[:, None, None, None].astype(np.float32)) if len(gains) else first


def control_variant(light: str = "drawn", exposure: str = "drawn") -> None:
    """The control row with its scenes' own lights and/or its real pairs' own levels (module
    docstring); 'drawn' for both builds exactly the task's own control."""
    from g2r_jax.downstream.base import thumbnails, training_sets
    from g2r_jax.downstream.isp import pairs, task
    from g2r_jax.pipeline import without_content

    original = task._RowSets.build

    def build(self, row, train, fold, seed):
        if row != "real_profile_light" or self.masks is None:
            return original(self, row, train, fold, seed)
        fitted = without_content(self.fitted(train, fold, seed))
        views = training_sets.real_to_linear_srgb(self.real.images[train], self.real.illuminants[train], self.profile,
                                                  size=self.real.images.shape[1])
        views = np.stack([thumbnails.area_average(v, self.view_size) for v in views])
        tiles = pairs.missing_tiles(self.real.images[train], size=self.size)
        levels = top_levels(self.pairs[0][train], self.masks[train])
        lights = np.asarray(self.real.illuminants[train], np.float32)
        views, masks, tiles, inputs, levels, lights = task._repeat_to(
            self.n, views, self.masks[train], tiles, self.pairs[0][train], levels, lights)
        neutrals = lights if light == "own" else None
        make = lambda v: pairs.g2r_pairs(v, fitted, 1000 * seed + 10 * fold + 8, neutrals=neutrals, size=self.size,
                                         saturated=tiles)
        packed, targets = _scaled_to(levels, make, views, masks) if exposure == "own" else make(views)
        return np.where(~masks[:, ::2, ::2, None], inputs, packed), targets, masks

    task._RowSets.build = build


def metered_exposure() -> None:
    """Every g2r_jax pair's level drawn from the real training pairs' levels (module docstring)."""
    from g2r_jax.downstream.isp import task

    original_build, original_g2r = task._RowSets.build, task._RowSets._g2r

    def build(self, row, train, fold, seed):
        self.training_files = train
        return original_build(self, row, train, fold, seed)

    def g2r(self, views, profile, salt, model=None, *, as_given=False, saturated=None, texture=None):
        train = self.training_files
        levels = top_levels(self.pairs[0][train], None if self.masks is None else self.masks[train])
        drawn = np.random.default_rng(salt + 77).choice(levels, len(views))
        make = lambda v: original_g2r(self, v, profile, salt, model, as_given=as_given, saturated=saturated,
                                      texture=texture)
        return _scaled_to(drawn, make, views, None)

    task._RowSets.build, task._RowSets._g2r = build, g2r


def joint_views(sets, train, fold: int, seed: int):
    """(the views of `sets` (a `task._RowSets`) for `seed`, each through the 'cast' model of one
    training file's scene, that file's light (n, 3), the files' casts (M, 3), the file drawn for each view (n,))."""
    from g2r_jax import content
    from g2r_jax.content.fitting import scene_cast_targets
    from g2r_jax.content.model import CAST_KEPT
    from g2r_jax.downstream.base.product import adapted_views

    images, lights = sets.real.images[train], np.asarray(sets.real.illuminants[train], np.float64)
    statistics = content.statistics(content.white_balanced_camera_rgb(images, lights), source="training folds")
    neutral = np.median(lights / lights[:, 1:2], axis=0)
    to_camera = content.srgb_to_camera_matrices(neutral[None], sets.profile.colour)[0]
    _, files, casts, _, _ = scene_cast_targets(statistics, to_camera)
    usable = np.all(np.isfinite(casts), axis=1)
    files, casts = files[usable], casts[usable]
    views = sets.views(seed)
    pick = np.random.default_rng(1000 * seed + 10 * fold + 5).integers(len(files), size=len(views))
    adapted = np.concatenate([adapted_views(content.content_model(family="cast", cast_target=casts[k], cast_scale=CAST_KEPT),
                                            views[i:i + 1]) for i, k in enumerate(pick)])
    return adapted, lights[files[pick]], casts, pick


def joint_scenes() -> None:
    """The 'fitted' row with each view's cast and light those of one training file (module docstring)."""
    from g2r_jax.downstream.isp import pairs, task
    from g2r_jax.pipeline import without_content

    original = task._RowSets.build

    def build(self, row, train, fold, seed):
        if row != "fitted":
            return original(self, row, train, fold, seed)
        adapted, lights, _, _ = joint_views(self, train, fold, seed)
        fitted = without_content(self.fitted(train, fold, seed))
        return pairs.g2r_pairs(adapted, fitted, 1000 * seed + 10 * fold + 4, neutrals=lights, size=self.size)

    task._RowSets.build = build


def texture_residuals(thumbnails: np.ndarray, size: int, sigma: float = 1.5) -> np.ndarray:
    """(N, size, size, 3) the fine texture of real thumbnails: each area-averaged to `size`, its
    log minus its Gaussian blur (`sigma` pixels) per channel, 0 within a pixel of a missing one."""
    from scipy.ndimage import binary_dilation, gaussian_filter

    out = np.zeros((len(thumbnails), size, size, 3), np.float32)
    for i, image in enumerate(np.asarray(thumbnails, np.float32)):
        small = _area(image, size)
        missing = binary_dilation(np.any(small <= 1e-4, axis=-1), iterations=1)
        logs = np.log(np.maximum(small, 0) + 2e-3)
        logs[missing] = np.log(np.mean(small[~missing], axis=0) + 2e-3) if (~missing).any() else 0.0
        blurred = np.stack([gaussian_filter(logs[..., c], sigma, mode="reflect") for c in range(3)], -1)
        out[i] = np.where(missing[..., None], 0.0, np.clip(logs - blurred, -1.5, 1.5))
    return out


def _area(image, size):
    h = image.shape[0] // size
    return image.reshape(size, h, size, h, 3).mean((1, 3))


def noise_residuals(residuals: np.ndarray, count: int, seed: int, sigma: float = 1.5) -> np.ndarray:
    """(count, h, w, 3) stationary Gaussian texture with the 3 x 3 covariance of `residuals`' pixels
    (their channels' log residuals; the pixels outside every texture, 0, left out): white noise,
    high-passed like `texture_residuals`, each channel scaled to unit sd, then correlated."""
    from scipy.ndimage import gaussian_filter

    pixels = residuals.reshape(-1, 3)
    pixels = pixels[np.any(pixels != 0, axis=1)]
    root = np.linalg.cholesky(np.cov(pixels.T) + 1e-9 * np.eye(3))
    z = np.random.default_rng(seed).standard_normal((count,) + residuals.shape[1:]).astype(np.float32)
    z -= np.stack([gaussian_filter(z[..., c], (0, sigma, sigma), mode="wrap") for c in range(3)], -1)
    z /= z.reshape(-1, 3).std(0)
    return np.clip(z @ root.T, -1.5, 1.5).astype(np.float32)


def textured(kind: str = "real") -> None:
    """Every g2r_jax row's views times the fine texture of random real training thumbnails
    ('real': `texture_residuals`, each view one file's, flipped at random; 'noise': `noise_residuals`
    of the same files' covariance), before they are made RAW; UPI's views too (its sRGB views clipped at 1)."""
    from g2r_jax.downstream.isp import task

    original_build, original_g2r = task._RowSets.build, task._RowSets._g2r

    def with_texture(self, views, salt):
        key = ("texture", tuple(self.training_files), views.shape[1])
        if key not in self.cache:
            self.cache[key] = texture_residuals(self.real.images[self.training_files], views.shape[1])
        residuals = self.cache[key]
        rng = np.random.default_rng(salt + 91)
        pick = residuals[rng.integers(len(residuals), size=len(views))]
        flips = rng.random(len(views)) < 0.5
        pick[flips] = pick[flips][:, :, ::-1]
        if kind == "noise":
            pick = noise_residuals(residuals, len(views), salt + 92)
        return (views * np.exp(pick)).astype(np.float32)

    def build(self, row, train, fold, seed):
        self.training_files = train
        if row == "upi":
            from g2r_jax.downstream.base import training_sets
            from g2r_jax.downstream.isp import pairs

            views = with_texture(self, self.views(seed), 1000 * seed + 10 * fold + 1)
            return pairs.upi_pairs(training_sets.linear_to_srgb_views(np.minimum(views, 1.0)), self.profile, seed + 1,
                                   size=self.size)
        return original_build(self, row, train, fold, seed)

    def g2r(self, views, profile, salt, model=None, *, as_given=False, saturated=None, texture=None):
        from g2r_jax.downstream.base.product import adapted_views

        if model is not None:
            views, model = adapted_views(model, views, salt), None
        return original_g2r(self, with_texture(self, views, salt), profile, salt, model, as_given=as_given,
                            saturated=saturated)

    task._RowSets.build, task._RowSets._g2r = build, g2r


def texture_scale(scale: float) -> None:
    """The g2r_jax rows' texture (`content.texture`) with its standard deviations times `scale`
    (its covariance times scale^2): the texture's amplitude chosen on training data (`--inner`)."""
    import dataclasses

    from g2r_jax.downstream.isp import task

    original = task._RowSets.texture_of

    def texture_of(self, images, where):
        model = original(self, images, where)
        if model is None:
            return None
        return dataclasses.replace(model, covariance=tuple(map(tuple, (np.asarray(model.covariance) * scale ** 2).tolist())))

    task._RowSets.texture_of = texture_of


def cast_only() -> None:
    """The g2r_jax rows take a 'scenes' content model's median cast (`content.as_cast`, what
    `g2r-convert --content-cast-only` takes for an ISP's pairs) even with the texture, as before
    the texture's order was chosen."""
    from g2r_jax.content import as_cast
    from g2r_jax.downstream.isp import task

    original = task._RowSets.content_model

    def content_model(self, images, lights, seed, where):
        model = original(self, images, lights, seed, where)
        return as_cast(model) if model is not None and model.family == "scenes" else model

    task._RowSets.content_model = content_model


def texture_after() -> None:
    """The g2r_jax rows' texture drawn onto the CG views after their content model instead of before
    it (the product's order: texture first)."""
    from g2r_jax.downstream.base.product import adapted_views
    from g2r_jax.downstream.isp import task

    original = task._RowSets._g2r

    def g2r(self, views, profile, salt, model=None, *, as_given=False, saturated=None, texture=None):
        if model is not None:
            views, model = adapted_views(model, views, salt), None
        return original(self, views, profile, salt, model, as_given=as_given, saturated=saturated, texture=texture)

    task._RowSets._g2r = g2r
