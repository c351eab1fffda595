"""Our boundary term against Mitsuba 3's projective sampling (``validation.edge_gradients``): the
derivative images of a sphere's and a box's motion, flat radiance over black."""

import pytest

pytestmark = [pytest.mark.mitsuba, pytest.mark.slow]
eg = pytest.importorskip("validation.edge_gradients")
pytest.importorskip("mitsuba")


def test_outline_derivatives_match_mitsubas_direct_projective():
    """A sphere moved along z and grown, and a turned box (a mesh whose faces share its corners)
    moved along x: ours within 3 % of Mitsuba's seed-averaged ``direct_projective`` beyond its own
    noise over the outline's pixels (the sphere's sums within two of its standard errors). Mitsuba's
    ``cube``, whose faces each have their own vertices, gives twice the truth (each edge is also
    the open boundary of two faces), as in mitsuba3 issue 1895."""
    sphere = eg.compare("sphere", width=24, height=18, spp=32, seeds=24, tangents=("centre z", "radius"))
    assert all(r.passed for r in sphere), [r.line() for r in sphere]
    (box,) = eg.compare("box", width=24, height=18, spp=32, seeds=24)
    assert box.rel_l2 <= eg.MAX_REL_L2 + box.noise, box.line()
    (cube,) = eg.compare("box", welded=False, width=24, height=18, spp=32, seeds=24)
    assert cube.mitsuba_to_ours == pytest.approx(2.0, rel=0.05), cube.line()
