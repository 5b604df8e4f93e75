"""Noise, in one place: `model` (the per-ISO heteroscedastic model and its sampling), `stream` (the
counter-based normal draws), `shape` (level function and spatial correlation), `estimation` (noise
measured from pixels), `fallback` (a profile's noise when files carry no NoiseProfile), `extension`
(the audit's fitted extension of the model)."""
