"""One training base for the downstream networks (the illuminant CNN and the burst denoiser).

Networks are equinox modules (pytrees of arrays, `eqx.Module`); the optimiser is Adam (Kingma &
Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015) from optax with one learning-rate
schedule, `learning_rate_schedule`: cosine decay from the peak to `final_fraction` of it
(Loshchilov & Hutter, "SGDR", ICLR 2017; `final_fraction` 1 keeps the rate constant). One loop,
`fit`: rounds of `steps_per_round` optimiser steps (one jitted `lax.scan` per round, or one
jitted step at a time: `LoopConfig.scan`), a
validation error after each round, the best round's model kept, and optional early stopping
when `patience` rounds in a row improve on the best by no more than `min_improvement`. With
`members`, `fit` trains several models at once (one vmapped program; their data stacked on a
leading axis), each keeping its own best round.

A network supplies `step_loss(model, step_input, data) -> scalar`: `step_input` is the
per-step slice of the round's inputs (a PRNG key, or crops cut in numpy), `data` the arrays
that stay fixed over the run (passed as arguments, not closed over, so that one compiled
program serves every set of the same shapes).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax


@dataclasses.dataclass(frozen=True)
class LoopConfig:
    """The loop of `fit`: at most `rounds` rounds of `steps_per_round` Adam steps; stop early when
    `patience` (None: never) rounds in a row fail to lower the best validation error by more than
    `min_improvement`; `learning_rate` peak of the schedule, decayed to `final_fraction` of it over
    the cap (`rounds * steps_per_round` steps). `scan`: a round is one `lax.scan` (fast for the
    CNN's matrix-product convolutions), else a Python loop of one jitted step each (XLA's CPU
    convolutions ran 3.5x slower per step inside a scan: 186 against 52 ms, the denoiser, 2 cores
    under load)."""

    rounds: int
    steps_per_round: int
    learning_rate: float
    final_fraction: float = 1.0
    patience: int | None = None
    min_improvement: float = 0.0
    scan: bool = True

    @property
    def max_steps(self) -> int:
        return self.rounds * self.steps_per_round


def learning_rate_schedule(peak: float, steps: int, final_fraction: float = 1.0):
    """The one schedule: cosine decay from `peak` to `final_fraction * peak` over `steps`
    (SGDR, Loshchilov & Hutter 2017, Eq. 5, one cycle); constant when `final_fraction` is 1."""
    if final_fraction == 1.0:
        return optax.constant_schedule(peak)
    return optax.cosine_decay_schedule(peak, max(int(steps), 1), alpha=final_fraction)


def optimiser_for(config: LoopConfig) -> optax.GradientTransformation:
    """Adam (optax) with `learning_rate_schedule` over the loop's cap."""
    return optax.adam(learning_rate_schedule(config.learning_rate, config.max_steps, config.final_fraction))


def _step_program(step_loss: Callable, optimiser: optax.GradientTransformation):
    """(model, opt_state, step_input, data) -> (model, opt_state, loss): one Adam step."""

    def step(model, state, step_input, data):
        loss, grads = eqx.filter_value_and_grad(step_loss)(model, step_input, data)
        updates, state = optimiser.update(grads, state, eqx.filter(model, eqx.is_array))
        return eqx.apply_updates(model, updates), state, loss

    return step


def _round_program(step):
    """(model, opt_state, step_inputs, data) -> (model, opt_state, mean loss): one `lax.scan` of
    `step` over the round's steps (step_inputs carry a leading axis of steps)."""

    def one_round(model, state, step_inputs, data):
        def body(carry, step_input):
            model, state, loss = step(*carry, step_input, data)
            return (model, state), loss

        (model, state), losses = jax.lax.scan(body, (model, state), step_inputs)
        return model, state, losses.mean()

    return one_round


def _looped_round(step):
    """As `_round_program`, one jitted step at a time from Python (`LoopConfig.scan` False)."""
    step = jax.jit(step)

    def one_round(model, state, step_inputs, data):
        losses = []
        for s in range(len(jax.tree_util.tree_leaves(step_inputs)[0])):
            model, state, loss = step(model, state, jax.tree_util.tree_map(lambda a: a[s], step_inputs), data)
            losses.append(loss)
        return model, state, jnp.mean(jnp.stack(losses))

    return one_round


@functools.lru_cache(maxsize=None)
def _compiled(step_loss: Callable, validate: Callable | None, config: LoopConfig, members: bool):
    optimiser = optimiser_for(config)
    step = _step_program(step_loss, optimiser)
    init = lambda model: optimiser.init(eqx.filter(model, eqx.is_array))
    if not config.scan:
        if members:
            raise ValueError("training several members at once needs LoopConfig.scan")
        return _looped_round(step), jax.jit(init), None if validate is None else jax.jit(validate)
    one_round = _round_program(step)
    if members:
        one_round, init = jax.vmap(one_round), jax.vmap(init)
        validate = None if validate is None else jax.vmap(validate)
    return jax.jit(one_round), jax.jit(init), None if validate is None else jax.jit(validate)


@dataclasses.dataclass
class FitResult:
    """`model` the kept model (the best round's when validated, else the last); `curve` (rounds,)
    validation errors (NaN without validation) and `losses` (rounds,) mean training losses, with a
    trailing member axis when `fit` trained several; `best_round` index (per member); `steps` Adam
    steps run (the same for every member)."""

    model: eqx.Module
    curve: np.ndarray
    losses: np.ndarray
    best_round: np.ndarray
    steps: int


def _keep_better(better, new, old):
    """Per member: `new` where `better` else `old` (array leaves only)."""
    def pick(a, b):
        mask = jnp.reshape(better, better.shape + (1,) * (a.ndim - better.ndim))
        return jnp.where(mask, a, b)
    return jax.tree_util.tree_map(pick, new, old)


def fit(model: eqx.Module, step_loss: Callable, round_inputs: Callable, data, config: LoopConfig, *,
        validate: Callable | None = None, validation_data=None, members: bool = False) -> FitResult:
    """Train `model` (see the module docstring); deterministic for deterministic inputs.

    **Arguments:** `step_loss(model, step_input, data)` the loss of one step (a module-level
    function: compiled programs are cached on it); `round_inputs(r)` the round's step inputs
    (leading axis `steps_per_round`; with `members`, a member axis before it); `data` the fixed
    arrays; `validate(model, validation_data)` a scalar error (lower is better), or None: then
    every round runs and the last model is kept.
    """
    one_round, init, check = _compiled(step_loss, validate, config, members)
    state = init(model)
    best = model
    width = (jax.tree_util.tree_leaves(model)[0].shape[0],) if members else ()
    best_error = np.full(width, np.inf)
    best_round = np.zeros(width, int)
    curve, losses, stale = [], [], 0
    for r in range(config.rounds):
        model, state, loss = one_round(model, state, round_inputs(r), data)
        losses.append(np.asarray(loss))
        if check is None:
            curve.append(np.full(width, np.nan))
            continue
        error = np.asarray(check(model, validation_data), np.float64)
        curve.append(error)
        improved = error < best_error - config.min_improvement
        better = error < best_error
        best = _keep_better(jnp.asarray(better), model, best) if members else (model if better else best)
        best_round = np.where(better, r, best_round)
        best_error = np.minimum(error, best_error)
        stale = 0 if np.any(improved) else stale + 1
        if config.patience is not None and stale >= config.patience:
            break
    kept = model if check is None else best
    return FitResult(model=kept, curve=np.asarray(curve), losses=np.asarray(losses),
                     best_round=np.asarray(len(losses) - 1 if check is None else best_round),
                     steps=len(losses) * config.steps_per_round)
