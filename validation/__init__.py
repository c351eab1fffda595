"""Validation of ``raytracer`` against Mitsuba 3 and POV-Ray 3.7.

* :mod:`validation.povray`  — run the real ``povray`` binary to a linear float image.
* :mod:`validation.mitsuba` — ``raytracer.Scene`` → Mitsuba scene dict; pixel-centre and film renders.
* :mod:`validation.metrics` — RMSE, PSNR, max / p99 error, fraction within tolerance, SSIM.
* :mod:`validation.suite`   — the scenes, their references and thresholds; running the comparisons.
* :mod:`validation.report`  — the HTML report with side-by-side images and diff heat maps.

``python -m validation`` (or ``raytracer validate``) runs the suite. Importing this package does not
import Mitsuba or JAX; the submodules do when used.
"""
