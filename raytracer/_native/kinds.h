// The native kernels' numbers, read by both sides: bvh.cc includes this file, and
// raytracer/shapes/_base.py reads it (``native_kinds``) for the shapes' ``native_kernel`` and
// raytracer/shading/_accel.py's KIND_CSG. One line per kind, "constexpr int KIND_<NAME> = <n>;".
#pragma once

constexpr int KIND_SPHERE = 0;
constexpr int KIND_BOX = 1;
constexpr int KIND_TRIANGLE = 2;
constexpr int KIND_FRUSTUM = 3;  // cylinder and cone: base, base radius, cap, cap radius, open
constexpr int KIND_DISC = 4;     // centre, normal, radius, hole radius
constexpr int KIND_TORUS = 5;    // major and minor radius (the x-z plane, the y axis through the hole)
constexpr int KIND_PLANE = 6;    // unit normal, distance: a member of a CSG unit only (it is unbounded)
constexpr int KIND_CSG = 7;      // a CSG unit: params[0] is its program's offset (see CSG units)
constexpr int KIND_SUPERELLIPSOID = 8;  // e, n (the unit box; shapes/_superellipsoid.py)
constexpr int KIND_QUADRIC = 9;  // A … J of Q(x) = 0 (shapes/_quadric.py): a member of a CSG unit only
constexpr int KIND_POLY = 10;    // 35 coefficients, two rows (see polynomial): a member of a CSG unit only
constexpr int KIND_PRISM = 11;   // a swept outline (prism, text) over several rows: see bvh.cc's prism
constexpr int KIND_LATHE = 12;  // a turned curve: a prism's layout (header, controls (r, y), senses)
constexpr int KIND_BLOB = 13;   // summed component fields: a header (N, threshold), then N components
constexpr int KIND_NONE = -1;    // a row that continues the item before it: never hit, never inside
