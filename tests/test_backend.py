"""Tests of raymitsuba/backend.py: the variant set up without Mitsuba's own AD integrators
(in a fresh process: the variant is process-wide), and loading them afterwards."""

from __future__ import annotations

import subprocess
import sys
import textwrap

LEAN = textwrap.dedent("""
    import sys
    from raymitsuba import backend
    mi = backend.mitsuba(mitsuba_integrators=False)
    assert mi.variant() == backend.variant()
    assert not [k for k in sys.modules if k.startswith(backend.AD_INTEGRATORS + ".")]
    try:
        mi.load_dict({"type": "prb"})
        raise SystemExit("prb loaded although skipped")
    except RuntimeError:
        pass
    import raymitsuba
    image = raymitsuba.render(raymitsuba.load("sphere\\nlight 1 1 1 point 0 0 5\\n", width=8, height=8))
    assert image.shape == (8, 8, 3)
    backend.mitsuba(mitsuba_integrators=True)  # loads them after all
    assert type(mi.load_dict({"type": "prb"})).__name__ == "PRBIntegrator"
    print("ok")
""")


def test_the_variant_without_mitsubas_ad_integrators_and_loading_them_later():
    result = subprocess.run([sys.executable, "-c", LEAN], capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.strip() == "ok"
