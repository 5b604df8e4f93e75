"""Profile JSON: round trip, validation with clear errors, shipped profiles."""

import json

import jax
import numpy as np
import pytest

from g2r_jax.profile import schema as pm
from g2r_jax.pipeline import unprocess


def test_every_shipped_profile_loads_round_trips_and_runs(tmp_path):
    names = pm.shipped_profiles()
    assert {"s20fe_night", "Canon600D", "gopro_hero6"} <= set(names)
    for name in names:
        profile = pm.load_profile(name)
        assert profile.info.provenance
        path = tmp_path / f"{name}.json"
        pm.save_profile(profile, path)
        again = pm.load_profile(path)
        assert_documents_close(pm.profile_to_dict(again), pm.profile_to_dict(profile))
    mosaic, _ = jax.jit(unprocess)(jax.random.PRNGKey(0), np.zeros((4, 6, 3), np.uint8), pm.load_profile("s20fe_night"))
    assert mosaic.shape == (4, 6)


def assert_documents_close(a, b, path="profile"):
    """Equal structure and strings; numbers equal to float32 precision."""
    assert type(a) is type(b) or isinstance(a, (int, float)) and isinstance(b, (int, float)), path
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for key in a:
            assert_documents_close(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, list) and a and isinstance(a[0], (list, int, float)):
        np.testing.assert_allclose(np.asarray(a, float), np.asarray(b, float), rtol=1e-6, atol=1e-9, err_msg=path)
    else:
        assert a == b, path


def broken(tmp_path, mutate):
    document = pm.profile_to_dict(pm.load_profile("Canon600D"))
    mutate(document)
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize("mutate, message", [
    (lambda d: d.update(version=99), "unsupported version 99"),
    (lambda d: d.update(schema="other"), "not a g2r_jax sensor profile"),
    (lambda d: d["colour"].update(color_matrices=[[1, 2, 3]]), "colour.color_matrices: expected shape"),
    (lambda d: d.update(cfa_pattern="RGBX"), "cfa_pattern"),
    (lambda d: d.update(cfa_pattern="RRGB"), "not a Bayer"),
    (lambda d: d.update(black_level=[70000] * 4), "below white_level"),
    (lambda d: d["illuminants"].update(kind="rainbow"), "unknown kind"),
    (lambda d: d.pop("colour"), "colour: missing"),
    (lambda d: d["colour"].update(calibration_illuminants=[255, 21]), "255"),
])
def test_invalid_profiles_name_the_file_and_the_problem(tmp_path, mutate, message):
    path = broken(tmp_path, mutate)
    with pytest.raises(pm.ProfileError, match=message) as error:
        pm.load_profile(path)
    assert str(path) in str(error.value)


def test_unknown_name_and_bad_json(tmp_path):
    with pytest.raises(pm.ProfileError, match="unknown profile name.*s20fe_night"):
        pm.load_profile("no_such_camera")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(pm.ProfileError, match="not valid JSON"):
        pm.load_profile(bad)


def test_profile_is_a_pytree_jit_argument_without_recompiling():
    traces = []

    @jax.jit
    def first_pixel(profile, key):
        traces.append(1)
        return unprocess(key, np.full((2, 2, 3), 128, np.uint8), profile, noise=False)[0][0, 0]

    a = pm.load_profile("Canon600D")
    b = pm.replace(a, white_level=a.white_level * 0.5)
    first_pixel(a, jax.random.PRNGKey(0))
    first_pixel(b, jax.random.PRNGKey(0))
    assert len(traces) == 1
