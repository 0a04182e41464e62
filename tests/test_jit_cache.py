"""The compiled core fails soft: without the package's cache locator, numba's own serves.

``allsky.jit_cache`` builds on private parts of numba. If a numba release
renames them, compiled calls must go on (one warning, numba's own cache),
and results must not change.
"""

import json
import os
import subprocess
import sys
import textwrap

import numba
import pytest

from allsky import jit_cache

needs_jit = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="about compiled code")

_WITHOUT_LOCATOR = textwrap.dedent("""
    import json, sys, warnings
    import numba.core.caching as caching
    if sys.argv[1] == "class":
        del caching._CacheLocator            # numba renamed its base class
    elif sys.argv[1] == "table":
        impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl
        impl._locator_classes = tuple(impl._locator_classes)   # a table that cannot grow
    import numpy as np
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        from allsky.vehicle import quaternion
        dcm = quaternion.dcm_body_from_inertial(np.array([0.5, 0.5, 0.5, 0.5]))
    print(json.dumps({"dcm": dcm.tolist(),
                      "warnings": [str(w.message) for w in seen
                                   if "cache locator" in str(w.message)]}))
""")


def _fly(tmp_path, how):
    env = {k: v for k, v in os.environ.items() if k not in ("ALLSKY_AOT",)}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / how), ALLSKY_AOT="0")
    out = subprocess.run([sys.executable, "-c", _WITHOUT_LOCATOR, how], capture_output=True,
                         text=True, timeout=300, env=env, check=True)
    return json.loads(out.stdout.splitlines()[-1])


@needs_jit
@pytest.mark.parametrize("how", ["class", "table"])
def test_compiled_calls_go_on_without_the_private_locator(tmp_path, how):
    reference = _fly(tmp_path, "none")
    fallback = _fly(tmp_path, how)
    assert reference["warnings"] == []
    assert fallback["dcm"] == reference["dcm"]
    assert len(fallback["warnings"]) == 1
    assert "numba's own" in fallback["warnings"][0]
    assert os.listdir(tmp_path / how)  # numba's own locator cached it


def test_the_locator_fits_this_numba():
    assert jit_cache.unavailable_reason() is None


def test_a_locator_numba_asks_more_of_is_not_used(monkeypatch):
    monkeypatch.setattr(jit_cache, "PROTOCOL", (*jit_cache.PROTOCOL, "get_new_thing"))
    assert jit_cache.unavailable_reason() == "numba's cache locator has no get_new_thing"
    monkeypatch.setattr(jit_cache, "_warned", [])
    with pytest.warns(RuntimeWarning, match="does not take allsky's cache locator"):
        assert jit_cache.install() is False
