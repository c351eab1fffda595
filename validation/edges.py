"""Independent references for the boundary term of a pixel's derivative (``raytracer/_edges.py``).

An outline whose curve is known in closed form is integrated per pixel exactly: the image region
``Q(u, v) ≥ 0`` of a conic ``Q`` (a sphere seen by a perspective or orthographic camera: its
outline is an ellipse in image coordinates) is parameterised by angle, cut where it crosses the
pixel grid (bisection to float64 precision), and each arc's ``∫ v_out ds`` is integrated by
Gauss–Legendre — the integrand is smooth on an arc, so the result is exact to rounding. With a
region of constant radiance ``L`` over black, the derivative of pixel P is ``L ∫_{Γ∩P} v_out ds``,
``v_out = Q_θ / |∇Q|`` the outward speed of the curve. Nothing here uses the renderer.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

_GAUSS = np.polynomial.legendre.leggauss(24)


def _direction_of(width: int, height: int, frame):
    """``(u, v) → ray direction`` (N, 3) through pixel coordinates of a perspective camera frame
    ``(location, D, R, U)``."""
    _, d, r, up = (np.asarray(x, np.float64) for x in frame)

    def direction(u, v):
        x0, y0 = u / width - 0.5, 0.5 - v / height
        return d[None, :] + x0[:, None] * r[None, :] + y0[:, None] * up[None, :]

    return direction


def sphere_conic(frame, centre, radius, width: int, height: int):
    """``(Q, Q_centre, Q_radius)``: the margin ``r²|d|² − |d × (c − eye)|²`` of the ray through image
    point (u, v) in pixels (positive where it sees the sphere) for a perspective camera ``frame``
    (``Camera.frame()``: location, D, R, U), and its derivatives along the centre (a (3,)
    direction) and the radius."""
    eye = np.asarray(frame[0], np.float64)
    centre = np.asarray(centre, np.float64)
    direction = _direction_of(width, height, frame)

    def q(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        cross = np.cross(d, centre - eye)
        return radius * radius * np.sum(d * d, -1) - np.sum(cross * cross, -1)

    def q_centre(u, v, e):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        cross = np.cross(d, centre - eye)
        return -2.0 * np.sum(cross * np.cross(d, np.asarray(e, np.float64)), -1)

    def q_radius(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        return 2.0 * radius * np.sum(d * d, -1)

    return q, q_centre, q_radius


def shadow_conic(frame, centre, radius, towards_light, plane_y: float, width: int, height: int):
    """The margin of the shadow that a sphere casts on the plane ``y = plane_y`` in a parallel light
    from direction ``towards_light``, as a quadratic in pixel coordinates (u, v) for a perspective
    camera ``frame``, positive where the ray through (u, v) meets the plane in the shadow.

    The plane point ``x = eye + t d`` (``t = (plane_y − eye_y)/d_y``) is in the shadow where the
    line ``x + s l`` passes within ``radius`` of ``centre``: ``|P (x − c)|² < r²``, ``P = I − l lᵀ``.
    Multiplied by ``d_y²``, with ``w = (eye − c) d_y + (plane_y − eye_y) d`` linear in d:
    ``Q = r² d_y² − wᵀ P w``."""
    eye = np.asarray(frame[0], np.float64)
    centre = np.asarray(centre, np.float64)
    l = np.asarray(towards_light, np.float64)
    l = l / np.linalg.norm(l)
    project_out = np.eye(3) - np.outer(l, l)
    direction = _direction_of(width, height, frame)

    def q(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        d_y = d[:, 1]
        w = (eye - centre)[None, :] * d_y[:, None] + (plane_y - eye[1]) * d
        return radius * radius * d_y * d_y - np.einsum("ni,ij,nj->n", w, project_out, w)

    return q


def cone_shadow_conic(frame, centre, radius, light, plane_y: float, width: int, height: int):
    """:func:`shadow_conic` for a light at the point ``light`` (a point light, or one sample of an
    area light's grid): the plane point ``x`` is in the shadow where it lies in the cone from the
    light that grazes the sphere, ``((x − q)·a)² ≥ (|a|² − r²)|x − q|²``, ``a = c − q`` (q the
    light). Multiplied by ``d_y²``, with ``w = (x − q) d_y = (eye − q) d_y + (plane_y − eye_y) d``
    linear in d: ``Q = (w·a)² − (|a|² − r²)|w|²``, a quadratic in (u, v)."""
    eye = np.asarray(frame[0], np.float64)
    q_light = np.asarray(light, np.float64)
    a = np.asarray(centre, np.float64) - q_light
    direction = _direction_of(width, height, frame)

    def q(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        w = (eye - q_light)[None, :] * d[:, 1:2] + (plane_y - eye[1]) * d
        return (w @ a) ** 2 - (a @ a - radius * radius) * np.sum(w * w, -1)

    return q


def plane_point(frame, plane_y: float, width: int, height: int):
    """``(u, v) → (N, 3)``: where the ray through image point (u, v) meets the plane ``y = plane_y``."""
    eye = np.asarray(frame[0], np.float64)
    direction = _direction_of(width, height, frame)

    def point(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        return eye[None, :] + ((plane_y - eye[1]) / d[:, 1])[:, None] * d

    return point


def sphere_through_slab(frame, centre, radius, z_near: float, z_far: float, ior: float, width: int,
                        height: int):
    """The margin of a sphere seen through a glass slab ``z_near ≤ z ≤ z_far`` of index ``ior``
    (the camera at ``z < z_near``), as a function of pixel coordinates (u, v), positive where the
    ray through (u, v) meets the sphere beyond the slab. The ray refracts into the slab (Snell) and
    out again parallel to itself: beyond the slab it is the line ``o' + s d``, ``o'`` the camera
    ray's origin shifted by the slab's lateral displacement; the margin is ``r²|d|² − |d × (c −
    o')|²``."""
    eye = np.asarray(frame[0], np.float64)
    centre = np.asarray(centre, np.float64)
    direction = _direction_of(width, height, frame)

    def q(u, v):
        d = direction(np.atleast_1d(u), np.atleast_1d(v))
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        entry = eye[None, :] + ((z_near - eye[2]) / d[:, 2])[:, None] * d
        eta, cos_i = 1.0 / ior, d[:, 2]  # the face's normal facing the ray is −z
        along_z = eta * cos_i - np.sqrt(1.0 - eta * eta * (1.0 - cos_i * cos_i))
        inside = eta * d - along_z[:, None] * np.array([0.0, 0.0, 1.0])
        exit_ = entry + ((z_far - z_near) / inside[:, 2])[:, None] * inside
        cross = np.cross(d, centre[None, :] - exit_)
        return radius * radius - np.sum(cross * cross, -1)

    return q


def _conic(q: Callable) -> tuple[np.ndarray, np.ndarray, float]:
    """``(A (2, 2), b (2,), c)`` with ``Q(p) = pᵀA p + 2 bᵀp + c``, from six values of the quadratic."""
    f = lambda u, v: float(q(np.array([u]), np.array([v]))[0])  # noqa: E731
    c = f(0.0, 0.0)
    a11 = (f(1.0, 0.0) + f(-1.0, 0.0)) / 2 - c
    a22 = (f(0.0, 1.0) + f(0.0, -1.0)) / 2 - c
    b1 = (f(1.0, 0.0) - f(-1.0, 0.0)) / 4
    b2 = (f(0.0, 1.0) - f(0.0, -1.0)) / 4
    a12 = (f(1.0, 1.0) - f(1.0, 0.0) - f(0.0, 1.0) + c) / 2
    return np.array([[a11, a12], [a12, a22]]), np.array([b1, b2]), c


def ellipse_outline_term(q: Callable, q_theta: Callable, width: int, height: int,
                         samples: int = 20_000, jump: Callable | None = None,
                         splits: tuple[Callable, ...] = ()) -> np.ndarray:
    """(H, W[, C]): ``∫_{Γ∩P} ΔL v_out ds`` per pixel for the ellipse ``Γ = {Q = 0}`` bounding
    ``Q ≥ 0`` (``Q`` a quadratic in the pixel coordinates u, v with a negative definite quadratic
    part), ``v_out = Q_θ/|∇Q|``. ``jump(u, v)`` (N,) or (N, C): the radiance inside minus outside
    at the outline (None: 1, so the sum is the derivative of the ellipse's area); ``splits``:
    functions of (u, v) where ``jump`` changes (arcs are cut where their sign does, so that each
    arc's integrand is smooth). It is the derivative of each pixel's box-filtered value where the
    radiance is constant on either side of the outline."""
    a, b, c = _conic(q)
    centre = np.linalg.solve(a, -b)
    level = c - b @ np.linalg.solve(a, b)  # Q at the centre
    lam, vec = np.linalg.eigh(-a)
    if not (np.all(lam > 0) and level > 0):
        raise ValueError("the conic is not an ellipse with an inside")
    axes = vec * np.sqrt(level / lam)[None, :]  # p(φ) = centre + axes @ (cos φ, sin φ)

    def point(phi):
        return centre[None, :] + np.stack([np.cos(phi), np.sin(phi)], -1) @ axes.T

    def tangent(phi):
        return np.stack([-np.sin(phi), np.cos(phi)], -1) @ axes.T

    def gradient(p):
        return 2.0 * (p @ a + b[None, :])

    return _closed_curve_term(point, tangent, gradient, q_theta, width, height, samples, jump, splits)


def star_outline_term(q: Callable, q_theta: Callable, centre, reach: float, width: int, height: int,
                      samples: int = 20_000, jump: Callable | None = None) -> np.ndarray:
    """:func:`ellipse_outline_term` for any smooth region ``Q ≥ 0`` that is star-shaped about
    ``centre`` (pixels) and lies within ``reach`` pixels of it: the outline's point at angle φ is
    the root of ``Q`` on the ray from ``centre`` (bisection to float64 precision), its tangent
    follows by implicit differentiation (``ρ' = −ρ ∇Q·e'/∇Q·e``), ``∇Q`` by central differences
    (``Q`` smooth: exact to ~1e-10 of its scale)."""
    centre = np.asarray(centre, np.float64)
    if not float(q(centre[:1], centre[1:])[0]) > 0:
        raise ValueError("the centre is not inside")

    def radius(phi):
        e = np.stack([np.cos(phi), np.sin(phi)], -1)
        lo, hi = np.zeros(len(phi)), np.full(len(phi), float(reach))
        end = centre[None, :] + hi[:, None] * e
        if np.any(q(end[:, 0], end[:, 1]) >= 0):
            raise ValueError("the region reaches farther than `reach`")
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            p = centre[None, :] + mid[:, None] * e
            inside = q(p[:, 0], p[:, 1]) >= 0
            lo, hi = np.where(inside, mid, lo), np.where(inside, hi, mid)
        return 0.5 * (lo + hi)

    def point(phi):
        return centre[None, :] + radius(phi)[:, None] * np.stack([np.cos(phi), np.sin(phi)], -1)

    def gradient(p, step=1e-5):
        g_u = (q(p[:, 0] + step, p[:, 1]) - q(p[:, 0] - step, p[:, 1])) / (2 * step)
        g_v = (q(p[:, 0], p[:, 1] + step) - q(p[:, 0], p[:, 1] - step)) / (2 * step)
        return np.stack([g_u, g_v], -1)

    def tangent(phi):
        p = point(phi)
        e = np.stack([np.cos(phi), np.sin(phi)], -1)
        e_perp = np.stack([-np.sin(phi), np.cos(phi)], -1)
        rho = np.linalg.norm(p - centre[None, :], axis=-1)
        g = gradient(p)
        rho_prime = -rho * np.sum(g * e_perp, -1) / np.sum(g * e, -1)
        return rho_prime[:, None] * e + rho[:, None] * e_perp

    return _closed_curve_term(point, tangent, gradient, q_theta, width, height, samples, jump, ())


def _closed_curve_term(point, tangent, gradient, q_theta, width, height, samples, jump, splits):
    """The per-pixel ``∫ ΔL v_out ds`` over a closed curve ``point(φ)``, φ ∈ [0, 2π): arcs cut where
    they cross the pixel grid (or a split changes sign), each integrated by Gauss–Legendre."""
    def cell(phi):
        p = point(phi)
        signs = tuple(np.asarray(f(p[:, 0], p[:, 1]) > 0, np.int64) for f in splits)
        return (np.floor(p[:, 0]).astype(np.int64), np.floor(p[:, 1]).astype(np.int64), *signs)

    phi = np.linspace(0.0, 2 * np.pi, samples + 1)
    key = np.stack(cell(phi), -1)
    changes = np.flatnonzero(np.any(key[1:] != key[:-1], axis=-1))
    lo, hi, start = phi[changes], phi[changes + 1], key[changes]
    for _ in range(60):  # every cut at once, to float64's resolution of φ
        mid = 0.5 * (lo + hi)
        same = np.all(np.stack(cell(mid), -1) == start, axis=-1)
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    cuts = np.concatenate([[0.0], 0.5 * (lo + hi), [2 * np.pi]])
    lo, hi = cuts[:-1], cuts[1:]
    arcs = hi > lo
    lo, hi = lo[arcs], hi[arcs]
    mid_u, mid_v = cell(0.5 * (lo + hi))[:2]
    nodes, weights = _GAUSS
    phis = (0.5 * (hi - lo))[:, None] * nodes[None, :] + (0.5 * (hi + lo))[:, None]  # (arcs, nodes)
    flat = phis.reshape(-1)
    p, t = point(flat), tangent(flat)
    speed = q_theta(p[:, 0], p[:, 1]) / np.linalg.norm(gradient(p), axis=-1)
    dl = np.ones(len(flat)) if jump is None else np.asarray(jump(p[:, 0], p[:, 1]), np.float64)
    w = (weights[None, :] * speed.reshape(phis.shape) * np.linalg.norm(t, axis=-1).reshape(phis.shape))
    value = 0.5 * (hi - lo)[:, None] * w  # (arcs, nodes)
    value = np.einsum("an,an...->a...", value, dl.reshape(*phis.shape, *dl.shape[1:]))
    out = np.zeros((height, width, *value.shape[1:]))
    keep = (mid_u >= 0) & (mid_u < width) & (mid_v >= 0) & (mid_v < height)
    np.add.at(out, (mid_v[keep], mid_u[keep]), value[keep])
    return out


def ellipse_area(q: Callable) -> float:
    """The area of ``{Q ≥ 0}`` (pixels²) in closed form: ``π Q(centre) / sqrt(det(−A))``."""
    a, b, c = _conic(q)
    level = c - b @ np.linalg.solve(a, b)
    return float(np.pi * level / np.sqrt(np.linalg.det(-a)))


def project(frame, width: int, height: int, points) -> np.ndarray:
    """World points (N, 3) → pixel coordinates (N, 2) (u right, v down) of a perspective camera
    ``frame`` (``Camera.frame()``: location, D, R, U): the ray through (u, v) passes the point."""
    eye, d, r, up = (np.asarray(x, np.float64) for x in frame)
    basis = np.stack([d, r, up], axis=1)  # columns
    a, b, c = np.linalg.solve(basis, (np.asarray(points, np.float64) - eye).T)
    x0, y0 = b / a, c / a
    return np.stack([(x0 + 0.5) * width, (0.5 - y0) * height], axis=-1)


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Indices of the convex hull of 2-D points, counter-clockwise (monotone chain)."""
    order = sorted(range(len(points)), key=lambda i: (points[i, 0], points[i, 1]))

    def cross(o, a, b):
        return (points[a, 0] - points[o, 0]) * (points[b, 1] - points[o, 1]) - \
               (points[a, 1] - points[o, 1]) * (points[b, 0] - points[o, 0])

    lower, upper = [], []
    for i in order:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], i) <= 0:
            lower.pop()
        lower.append(i)
    for i in reversed(order):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], i) <= 0:
            upper.pop()
        upper.append(i)
    return np.array(lower[:-1] + upper[:-1])


def segments_term(ends, motions, jumps, width: int, height: int) -> np.ndarray:
    """(H, W): ``Σ ∫_{segment ∩ P} jump · v_n ds`` per pixel for straight image segments ``ends`` (N, 2,
    2) (two ends each, pixels) moving at ``motions`` (N, 2, 2) (pixels per unit of the parameter;
    a segment's points move as the affine blend of its ends' motions, as the image of a straight
    3-D edge does), ``v_n`` the speed along the segment's normal ``(e_v, −e_u)/|e|`` (``e`` = second
    end − first) and ``jumps`` (N,) the radiance on the side the normal points away from minus the
    other. Each piece within one pixel is integrated by Gauss–Legendre (exact: v_n is linear)."""
    out = np.zeros((height, width))
    nodes, weights = _GAUSS
    for (p, q), (vp, vq), jump in zip(np.asarray(ends, np.float64), np.asarray(motions, np.float64),
                                      np.asarray(jumps, np.float64), strict=True):
        edge = q - p
        length = np.linalg.norm(edge)
        if length == 0:
            continue
        normal = np.array([edge[1], -edge[0]]) / length
        cuts = {0.0, 1.0}  # where the segment crosses a grid line
        for axis in (0, 1):
            if edge[axis] != 0:
                lo, hi = sorted((p[axis], q[axis]))
                for line in range(int(np.ceil(lo)), int(np.floor(hi)) + 1):
                    s = (line - p[axis]) / edge[axis]
                    if 0 < s < 1:
                        cuts.add(s)
        cuts = sorted(cuts)
        for s0, s1 in zip(cuts[:-1], cuts[1:], strict=True):
            mid = p + 0.5 * (s0 + s1) * edge
            col, row = int(np.floor(mid[0])), int(np.floor(mid[1]))
            if not (0 <= col < width and 0 <= row < height):
                continue
            s = 0.5 * (s1 - s0) * nodes + 0.5 * (s1 + s0)
            motion = (1 - s)[:, None] * vp + s[:, None] * vq
            out[row, col] += jump * 0.5 * (s1 - s0) * length * np.sum(weights * (motion @ normal))
    return out


def convex_outline_term(points, velocities, width: int, height: int) -> np.ndarray:
    """(H, W): ``∫_{Γ∩P} v_out ds`` per pixel for the outline Γ of the convex hull of the image
    points ``points`` (N, 2) moving at ``velocities`` (N, 2) (pixels per unit of the parameter),
    radiance 1 inside and 0 outside (``segments_term`` of the hull's edges, counter-clockwise, so
    each edge's normal points out). A box's outline is the hull of its eight projected corners
    (all in front of the camera)."""
    points, velocities = np.asarray(points, np.float64), np.asarray(velocities, np.float64)
    hull = _convex_hull(points)
    ends = np.stack([points[hull], points[np.roll(hull, -1)]], axis=1)
    motions = np.stack([velocities[hull], velocities[np.roll(hull, -1)]], axis=1)
    return segments_term(ends, motions, np.ones(len(hull)), width, height)


def checker_floor_term(frame_at, offset, size: float, height_y: float, colours, width: int, height: int,
                       cells: int = 12) -> np.ndarray:
    """(H, W): the boundary term of a checker floor ``y = height_y`` (cells of ``size``, shifted by
    ``offset`` (x, z); cell (i, j) has colour ``colours[(i + j + floor(height_y/size)) % 2]``) for a
    camera whose frame is ``frame_at(s)`` at parameter s (its derivative at 0 by central
    differences): every cell edge within ``cells`` of the origin is a straight segment of the image
    whose ends move as their projections do. Edges that reach behind the camera are left out (the
    scene must keep the floor's visible edges well in front of it)."""
    eps = 1e-6
    f0, fp, fm = frame_at(0.0), frame_at(eps), frame_at(-eps)
    forward = np.asarray(f0[1], np.float64) / np.linalg.norm(f0[1])
    layer = int(np.floor(height_y / size))
    ends, motions, jumps = [], [], []
    for i in range(-cells, cells + 1):
        for j in range(-cells, cells + 1):
            x, z = i * size + offset[0], j * size + offset[1]
            for a, b, left, right in (((x, z), (x, z + size), (i - 1, j), (i, j)),   # along z
                                      ((x, z), (x + size, z), (i, j), (i, j - 1))):  # along x
                points = np.array([[a[0], height_y, a[1]], [b[0], height_y, b[1]]])
                if np.any((points - np.asarray(f0[0])) @ forward <= 0.1):
                    continue
                ends.append(project(f0, width, height, points))
                motions.append((project(fp, width, height, points)
                                - project(fm, width, height, points)) / (2 * eps))
                jumps.append((left, right))
    out = np.zeros((height, width))
    ends, motions = np.asarray(ends), np.asarray(motions)
    for n, ((ci, cj), (di, dj)) in enumerate(jumps):
        # the normal (e_v, −e_u) of the image segment: which cell it points away from is decided in
        # the image, by the projected centre of one of the two cells
        edge = ends[n, 1] - ends[n, 0]
        normal = np.array([edge[1], -edge[0]])
        centre = project(f0, width, height, np.array([[(ci + 0.5) * size + offset[0], height_y,
                                                        (cj + 0.5) * size + offset[1]]]))[0]
        first, second = (ci, cj), (di, dj)
        if np.dot(centre - ends[n, 0], normal) > 0:  # the normal points into the first cell
            first, second = second, first
        jump = colours[(first[0] + first[1] + layer) % 2] - colours[(second[0] + second[1] + layer) % 2]
        out += segments_term(ends[n:n + 1], motions[n:n + 1], [jump], width, height)
    return out


def stripe_floor_term(frame_at, shift: float, size: float, height_y: float, colours, width: int, height: int,
                      stripes: int = 24, length: float = 12.0) -> np.ndarray:
    """(H, W): the boundary term of a floor ``y = height_y`` striped along x: colour ``colours[0]``
    where the fractional part of ``(x + shift) / size`` is below ½, ``colours[1]`` above (POV-Ray's
    ``gradient x`` with the map ``[0 A] [0.5 A] [0.5 B] [1 B]``, scaled by ``size`` and moved by
    ``−shift``; ``x + shift`` positive where seen), for a camera whose frame is ``frame_at(s)``: each
    stripe edge within ``stripes`` half-periods of x = −shift is straight, cut into pieces of ``size``
    along z up to ``length``, each a segment of the image whose ends move as their projections do
    (pieces that reach behind the camera are left out)."""
    f0, fp, fm, eps = _frames(frame_at)
    forward = np.asarray(f0[1], np.float64) / np.linalg.norm(f0[1])
    out = np.zeros((height, width))
    for n in range(stripes):
        x = 0.5 * n * size - shift
        # going +x across it: into colour 1 at an odd half (a step at ½), into colour 0 at a whole one
        before, after = (colours[0], colours[1]) if n % 2 else (colours[1], colours[0])
        for z in np.arange(-length, length, size):
            points = np.array([[x, height_y, z], [x, height_y, z + size]])
            if np.any((points - np.asarray(f0[0])) @ forward <= 0.1):
                continue
            ends = project(f0, width, height, points)
            motion = (project(fp, width, height, points) - project(fm, width, height, points)) / (2 * eps)
            edge = ends[1] - ends[0]
            normal = np.array([edge[1], -edge[0]])
            ahead = project(f0, width, height, np.array([[x + 0.1 * size, height_y, z + 0.5 * size]]))[0]
            # the jump: the radiance on the side the normal points away from minus the other
            jump = before - after if np.dot(ahead - ends[0], normal) > 0 else after - before
            out += segments_term(ends[None], motion[None], [jump], width, height)
    return out


def _frames(frame_at, eps: float = 1e-6):
    """The camera's frame at the parameter's 0 and ±eps (its motion by central differences)."""
    return frame_at(0.0), frame_at(eps), frame_at(-eps), eps


def _floor_edge(frames, a, b, height_y: float, centre, brighter: float, width: int, height: int):
    """(H, W): the term of the straight floor edge from (x, z) ``a`` to ``b`` on ``y = height_y``,
    whose side holding the floor point (x, z) ``centre`` is ``brighter`` than the other: its image
    segment moves as its ends' projections do (zero if it reaches behind the camera)."""
    f0, fp, fm, eps = frames
    forward = np.asarray(f0[1], np.float64) / np.linalg.norm(f0[1])
    points = np.array([[a[0], height_y, a[1]], [b[0], height_y, b[1]]])
    if np.any((points - np.asarray(f0[0])) @ forward <= 0.1):
        return 0.0
    ends = project(f0, width, height, points)
    motion = (project(fp, width, height, points) - project(fm, width, height, points)) / (2 * eps)
    edge = ends[1] - ends[0]
    seen = project(f0, width, height, np.array([[centre[0], height_y, centre[1]]]))[0]
    into = np.dot(seen - ends[0], [edge[1], -edge[0]]) > 0  # the segment's normal points into centre's side
    return segments_term(ends[None], motion[None], [-brighter if into else brighter], width, height)


def hexagon_floor_term(frame_at, size: float, height_y: float, colours, width: int, height: int,
                       cells: int = 8) -> np.ndarray:
    """(H, W): :func:`checker_floor_term` for POV-Ray's ``hexagon`` pattern on the floor ``y =
    height_y``, scaled by ``size``: hexagons of side ``size`` in x-z with vertices on ±x, centred at
    size·(1.5 i, √3 (j + i/2)), cell (i, j) of colour ``colours[(j − i) mod 3]``. Each edge, between
    two neighbouring centres, is a straight image segment whose ends move as their projections do."""
    frames = _frames(frame_at)
    root3 = np.sqrt(3.0)

    def centre(i, j):
        return np.array([1.5 * i, root3 * (j + 0.5 * i)]) * size

    out = np.zeros((height, width))
    # each cell's edges towards the neighbours (i + 1, j), (i, j + 1), (i + 1, j − 1): every edge once
    for i in range(-cells, cells + 1):
        for j in range(-cells, cells + 1):
            c = centre(i, j)
            for di, dj in ((1, 0), (0, 1), (1, -1)):
                n = centre(i + di, j + dj)
                mid, along = 0.5 * (c + n), np.array([-(n - c)[1], (n - c)[0]]) / (2 * root3)  # half a side
                # the edge's two vertices (|b − a| = size), (i, j)'s side brighter by the difference
                brighter = colours[(j - i) % 3] - colours[(j + dj - i - di) % 3]
                out = out + _floor_edge(frames, mid - along, mid + along, height_y, c, brighter,
                                        width, height)
    return out


def brick_floor_term(frame_at, scale: float, height_y: float, colours, width: int, height: int,
                     size=(8.0, 3.0, 4.5), mortar: float = 0.5, cells: int = 12) -> np.ndarray:
    """(H, W): :func:`checker_floor_term` for POV-Ray's ``brick`` pattern (``brick_size`` ``size``,
    ``mortar``, scaled by ``scale``) on the floor ``y = height_y``, which must cut a row of bricks:
    in pattern space the row's bricks are the rectangles x ∈ [8k + sx, 8k + sx + 8 − mortar],
    z ∈ [4.5m + sz, 4.5m + sz + 4.5 − mortar] (odd rows shifted half a brick in x, even ones in z),
    ``colours`` = (mortar, brick). Each rectangle's four edges are straight image segments with the
    brick inside."""
    frames = _frames(frame_at)
    bx, by, bz = size
    row = np.floor(height_y / scale / by)
    if (height_y / scale - row * by) >= by - mortar:
        raise ValueError("the floor lies in a mortar layer")
    odd = row % 2 == 1
    sx, sz = (-0.5 * bx, 0.0) if odd else (0.0, -0.5 * bz)
    out = np.zeros((height, width))
    for k in range(-cells, cells + 1):
        for m in range(-2 * cells, 2 * cells + 1):
            x0, z0 = (bx * k + sx) * scale, (bz * m + sz) * scale
            x1, z1 = x0 + (bx - mortar) * scale, z0 + (bz - mortar) * scale
            centre = (0.5 * (x0 + x1), 0.5 * (z0 + z1))
            corners = [(x0, z0), (x1, z0), (x1, z1), (x0, z1)]
            for a, b in zip(corners, corners[1:] + corners[:1], strict=True):
                out = out + _floor_edge(frames, a, b, height_y, centre, colours[1] - colours[0],
                                        width, height)
    return out


def open_tube_outline_term(base, cap, radius: float, d_radius: float, d_centre, extent, width: int,
                           height: int) -> np.ndarray:
    """(H, W): ``∫_{Γ∩P} ΔL v_out ds`` per pixel, radiance 1 on the tube and 0 elsewhere, for an
    open cylinder (``base``, ``cap``: 3-D, differing in x and z only) seen by an orthographic camera
    along +z whose image spans ``extent`` = (width, height) about the origin, the radius moving at
    ``d_radius`` and the whole cylinder at ``d_centre`` (x, y).

    Each rim projects to an ellipse ``Q ≥ 0``, ``Q(p) = r² − |p − c|² − (n_xy·(p − c))²/n_z²`` (n
    the axis). The tube covers the hull of the two ellipses less their overlap, through which a line
    passes both openings and misses the side: its outline is each ellipse's outer half, the two
    lines that touch both (y = c_y ± r), and each ellipse's arc inside the other, where the
    covered side is outside. ``Q_θ = 2 r ṙ − ∇Q·ċ``."""
    base, cap = np.asarray(base, np.float64), np.asarray(cap, np.float64)
    if base[1] != cap[1]:
        raise ValueError("base and cap must differ in x and z only")
    axis = (cap - base) / np.linalg.norm(cap - base)
    w_world, h_world = extent
    d_centre = np.asarray(d_centre, np.float64)

    def world(u, v):
        return (u / width - 0.5) * w_world, (0.5 - v / height) * h_world

    def pixel_u(x):
        return (x / w_world + 0.5) * width

    def rim(centre, r):
        def q(u, v):
            x, y = world(u, v)
            px, py = x - centre[0], y - centre[1]
            return r * r - px * px - py * py - (axis[0] * px) ** 2 / axis[2] ** 2
        return q

    def rate(centre):
        def q_theta(u, v):
            x, y = world(u, v)
            px, py = x - centre[0], y - centre[1]
            grad = np.stack([-2 * px - 2 * axis[0] ** 2 * px / axis[2] ** 2, -2 * py], -1)  # ∇Q, world
            return 2 * radius * d_radius - grad @ d_centre
        return q_theta

    (c1, c2) = sorted([base[:2], cap[:2]], key=lambda c: c[0])
    q1, q2 = rim(c1, radius), rim(c2, radius)
    u1, u2 = pixel_u(c1[0]), pixel_u(c2[0])
    out = ellipse_outline_term(q1, rate(c1), width, height,
                               jump=lambda u, v: np.where(q2(u, v) > 0, -1.0, np.where(u < u1, 1.0, 0.0)),
                               splits=(lambda u, v: u - u1, q2))
    out += ellipse_outline_term(q2, rate(c2), width, height,
                                jump=lambda u, v: np.where(q1(u, v) > 0, -1.0, np.where(u > u2, 1.0, 0.0)),
                                splits=(lambda u, v: u - u2, q1))
    # the lines touching both ellipses at their top and bottom, moving with the radius and the centre
    scale = np.array([width / w_world, -height / h_world])

    def to_pixels(x, y):
        return np.array([pixel_u(x), (0.5 - y / h_world) * height])

    ends, motions = [], []
    for side in (1.0, -1.0):
        y = c1[1] + side * radius
        left, right = to_pixels(c1[0], y), to_pixels(c2[0], y)
        ends.append([left, right] if side > 0 else [right, left])  # each normal points off the tube
        motion = (d_centre + np.array([0.0, side * d_radius])) * scale
        motions.append([motion, motion])
    return out + segments_term(ends, motions, np.ones(2), width, height)
