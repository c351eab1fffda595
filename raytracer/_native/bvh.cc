// A bounding volume hierarchy over a scene's primitives, called from JAX through XLA's FFI.
//
// It only *chooses*: which item a ray hits first (closest hit), whether anything blocks a shadow
// segment (any hit), or which items a filtered shadow segment crosses (all hits, the nearest k). The distance and normal the renderer uses are then computed again by the chosen
// primitive's JAX kernel, so gradients never pass through this file (a preliminary intersection
// followed by a differentiable surface interaction, as in Mitsuba 3).
//
// Items. An item is one primitive (a sphere, a box) or one triangle of a mesh. Each carries
// ITEM_PARAMS numbers: its object_from_world affine map (3×4, row-major) and its shape in object
// space (sphere: centre, radius; box: two corners; triangle: three vertices; torus: its radii;
// superellipsoid: e, n; plane: normal,
// distance, only as a member of a CSG unit, below). The intersections
// below are computed in double precision whatever the input type.
//
// Layout of the hierarchy (written by bvh_build, M = 2n - 1 nodes at most, root 0): node_box (M, 6) =
// lo xyz, hi xyz; node_info (M, 4) int32: a leaf is [first, count > 0, 0, 0] and holds the items
// order[first : first + count]; an inner node is [left, 0, right, axis], `axis` its split axis (the
// child on the ray's near side is visited first).
//
// Ties (semantics §4.4). Two coincident surfaces are hit at the same distance; POV-Ray shows the one
// its own bounding hierarchy tests first: the object whose box the ray enters first, else the earlier
// in the file. Every item names its bounding unit (unit, an index in file order), and unit_box (U, 6)
// holds the units' boxes; the closest-hit query treats crossings within TIE_EPSILONS relative machine
// epsilons of the nearest as tied and keeps the tied item whose unit wins that order.
//
// Build: binned surface-area heuristic over item centroids (16 bins on each axis), leaves of at most
// 4 items unless splitting does not pay, a median split when every centroid falls in one bin.

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "xla/ffi/api/ffi.h"
#include "kinds.h"

namespace ffi = xla::ffi;

namespace {

constexpr int ITEM_PARAMS = 24;
// the kernels' numbers: kinds.h, which the Python side reads too
constexpr int MEMBER_INTS = 4;  // a CSG member's entry in its unit's program (see CSG units)
constexpr int MAX_CROSSINGS = 8; // crossings of one member a CSG unit looks at (a frustum has 4)
constexpr int BINS = 16;
constexpr int MAX_LEAF = 4;
constexpr int STACK = 128;
constexpr int64_t SAH_DEPTH = 64;  // below this depth, median splits (see build)

struct Box3 {
  double lo[3] = {INFINITY, INFINITY, INFINITY};
  double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  void grow(const Box3& b) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], b.lo[k]);
      hi[k] = std::max(hi[k], b.hi[k]);
    }
  }
  void grow(const double* p) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  double area() const {
    double e[3];
    for (int k = 0; k < 3; ++k) e[k] = std::max(0.0, hi[k] - lo[k]);
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
  }
};

// ------------------------------------------------------------------------------------------ build
template <typename T>
int64_t build(const T* boxes, int64_t n, T* node_box, int32_t* node_info, int32_t* order) {
  std::vector<Box3> item(n);
  std::vector<double> cen(3 * n);
  for (int64_t i = 0; i < n; ++i) {
    // inflate each box a little so that rounding in the box (float32) never loses a hit
    double scale = 0.0;
    for (int k = 0; k < 6; ++k) {
      double v = static_cast<double>(boxes[6 * i + k]);
      if (std::isfinite(v)) scale = std::max(scale, std::fabs(v));
    }
    double pad = 1e-6 * scale + 1e-30;
    for (int k = 0; k < 3; ++k) {
      double lo = static_cast<double>(boxes[6 * i + k]), hi = static_cast<double>(boxes[6 * i + 3 + k]);
      if (!(lo <= hi)) lo = hi = 0.0;  // an empty or NaN box: a point (its item is never hit anyway)
      item[i].lo[k] = lo - pad;
      item[i].hi[k] = hi + pad;
      cen[3 * i + k] = 0.5 * (lo + hi);
    }
  }
  for (int64_t i = 0; i < n; ++i) order[i] = static_cast<int32_t>(i);

  struct Task {
    int64_t node, begin, end, depth;
  };
  std::vector<Task> tasks;
  tasks.push_back({0, 0, n, 0});
  int64_t n_nodes = 1;
  while (!tasks.empty()) {
    Task task = tasks.back();
    tasks.pop_back();
    Box3 bounds, cbounds;
    for (int64_t i = task.begin; i < task.end; ++i) {
      bounds.grow(item[order[i]]);
      cbounds.grow(&cen[3 * order[i]]);
    }
    for (int k = 0; k < 3; ++k) {
      node_box[6 * task.node + k] = static_cast<T>(bounds.lo[k]);
      node_box[6 * task.node + 3 + k] = static_cast<T>(bounds.hi[k]);
    }
    // rounding the node box to T must not shrink it
    for (int k = 0; k < 3; ++k) {
      T& lo = node_box[6 * task.node + k];
      T& hi = node_box[6 * task.node + 3 + k];
      if (static_cast<double>(lo) > bounds.lo[k]) lo = std::nextafter(lo, -std::numeric_limits<T>::infinity());
      if (static_cast<double>(hi) < bounds.hi[k]) hi = std::nextafter(hi, std::numeric_limits<T>::infinity());
    }
    int32_t* info = node_info + 4 * task.node;
    const int64_t count = task.end - task.begin;
    auto make_leaf = [&] {
      info[0] = static_cast<int32_t>(task.begin);
      info[1] = static_cast<int32_t>(count);
      info[2] = 0;
      info[3] = 0;
    };
    if (count <= 1) {
      make_leaf();
      continue;
    }
    // binned SAH over the three axes
    int best_axis = -1, best_bin = -1;
    double best_cost = INFINITY;
    for (int axis = 0; axis < 3; ++axis) {
      const double lo = cbounds.lo[axis], extent = cbounds.hi[axis] - cbounds.lo[axis];
      if (!(extent > 0.0)) continue;
      Box3 bin_box[BINS];
      int64_t bin_count[BINS] = {0};
      for (int64_t i = task.begin; i < task.end; ++i) {
        int b = static_cast<int>(BINS * (cen[3 * order[i] + axis] - lo) / extent);
        b = std::min(std::max(b, 0), BINS - 1);
        bin_count[b] += 1;
        bin_box[b].grow(item[order[i]]);
      }
      double right_area[BINS];
      int64_t right_count[BINS];
      Box3 acc;
      int64_t c = 0;
      for (int b = BINS - 1; b > 0; --b) {
        acc.grow(bin_box[b]);
        c += bin_count[b];
        right_area[b] = acc.area();
        right_count[b] = c;
      }
      Box3 left;
      int64_t lc = 0;
      for (int b = 1; b < BINS; ++b) {
        left.grow(bin_box[b - 1]);
        lc += bin_count[b - 1];
        if (lc == 0 || right_count[b] == 0) continue;
        double cost = left.area() * lc + right_area[b] * right_count[b];
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_bin = b;
        }
      }
    }
    const double leaf_cost = bounds.area() * count;
    // traversal cost ~ one item test: split when it pays, always when the leaf would be large
    if (best_axis >= 0 && count <= MAX_LEAF && best_cost + bounds.area() >= leaf_cost) {
      make_leaf();
      continue;
    }
    int64_t mid;
    int axis;
    if (best_axis >= 0 && task.depth < SAH_DEPTH) {
      axis = best_axis;
      const double lo = cbounds.lo[axis], extent = cbounds.hi[axis] - cbounds.lo[axis];
      int32_t* split = std::partition(order + task.begin, order + task.end, [&](int32_t it) {
        int b = static_cast<int>(BINS * (cen[3 * it + axis] - lo) / extent);
        return std::min(std::max(b, 0), BINS - 1) < best_bin;
      });
      mid = split - order;
    } else {
      // every centroid coincides, or the tree is already deep: a median split on the widest axis
      // (it bounds the depth, and so the traversal stack, by SAH_DEPTH + log2 n)
      axis = 0;
      for (int k = 1; k < 3; ++k)
        if (cbounds.hi[k] - cbounds.lo[k] > cbounds.hi[axis] - cbounds.lo[axis]) axis = k;
      mid = task.begin + count / 2;
      std::nth_element(order + task.begin, order + mid, order + task.end,
                       [&](int32_t a, int32_t b) { return cen[3 * a + axis] < cen[3 * b + axis]; });
    }
    if (mid == task.begin || mid == task.end) mid = task.begin + count / 2;
    const int64_t left = n_nodes, right = n_nodes + 1;
    n_nodes += 2;
    info[0] = static_cast<int32_t>(left);
    info[1] = 0;
    info[2] = static_cast<int32_t>(right);
    info[3] = axis;
    tasks.push_back({right, mid, task.end, task.depth + 1});
    tasks.push_back({left, task.begin, mid, task.depth + 1});
  }
  return n_nodes;
}

// ------------------------------------------------------------------------------------------ items
// fmin and fmax (a NaN operand gives the other), written out: the library's are calls (through
// the PLT) that the compiler does not inline without -ffinite-math-only, 12 per box test
inline double min_num(double a, double b) { return (b < a || a != a) ? b : a; }
inline double max_num(double a, double b) { return (b > a || a != a) ? b : a; }

struct RayD {
  double o[3], d[3];
};

inline RayD to_object(const double* m, const double* o, const double* d) {
  RayD r;
  for (int i = 0; i < 3; ++i) {
    r.o[i] = m[4 * i] * o[0] + m[4 * i + 1] * o[1] + m[4 * i + 2] * o[2] + m[4 * i + 3];
    r.d[i] = m[4 * i] * d[0] + m[4 * i + 1] * d[1] + m[4 * i + 2] * d[2];
  }
  return r;
}

inline double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

inline void keep_first(double t, double tmin, double& best) {
  if (t > tmin && t < best) best = t;
}

// The first crossing of a cylinder or cone (a frustum: |p⊥|² = r(h)², r(h) = r_base + k h for the
// height h along the axis, 0 ≤ h ≤ L) and, unless open, its two end caps, with t in (tmin, tmax).
inline double frustum_hit(const double* q, const RayD& r, double tmin, double tmax) {
  const double *base = q, *cap = q + 4;
  const double rb = q[3], rc = q[7];
  const bool open = q[8] != 0.0;
  double axis[3] = {cap[0] - base[0], cap[1] - base[1], cap[2] - base[2]};
  const double length = std::sqrt(dot3(axis, axis));
  if (!(length > 0.0)) return INFINITY;
  for (double& a : axis) a /= length;
  const double slope = (rc - rb) / length;
  double l[3] = {r.o[0] - base[0], r.o[1] - base[1], r.o[2] - base[2]};
  const double h0 = dot3(l, axis), hd = dot3(r.d, axis);
  double lp[3], dp[3];
  for (int k = 0; k < 3; ++k) {
    lp[k] = l[k] - h0 * axis[k];
    dp[k] = r.d[k] - hd * axis[k];
  }
  const double r0 = rb + slope * h0;
  const double A = dot3(dp, dp) - (slope * hd) * (slope * hd);
  const double B = 2.0 * (dot3(lp, dp) - slope * hd * r0);
  const double C = dot3(lp, lp) - r0 * r0;
  double best = tmax;
  auto side = [&](double t) {
    const double h = h0 + t * hd;
    if (h >= 0.0 && h <= length) keep_first(t, tmin, best);
  };
  if (A != 0.0) {
    const double disc = B * B - 4.0 * A * C;
    if (disc >= 0.0) {
      const double qq = -0.5 * (B + std::copysign(std::sqrt(disc), B));
      side(qq / A);
      if (qq != 0.0) side(C / qq);
    }
  } else if (B != 0.0) {
    side(-C / B);
  }
  if (!open && hd != 0.0) {
    const double ends[2][2] = {{0.0, rb}, {length, rc}};
    for (const auto& end : ends) {
      const double t = (end[0] - h0) / hd;
      double p[3] = {lp[0] + t * dp[0], lp[1] + t * dp[1], lp[2] + t * dp[2]};
      if (dot3(p, p) <= end[1] * end[1]) keep_first(t, tmin, best);
    }
  }
  return best < tmax ? best : INFINITY;
}

// The real roots of s³ + p s + q in ascending order (1 or 3 of them); returns how many.
inline int cubic_roots(double p, double q, double* out) {
  if (p == 0.0 && q == 0.0) {
    out[0] = 0.0;
    return 1;
  }
  const double h = 0.25 * q * q + p * p * p / 27.0;
  if (h > 0.0) {  // one real root (Cardano)
    const double sq = std::sqrt(h);
    out[0] = std::cbrt(-0.5 * q + sq) + std::cbrt(-0.5 * q - sq);
    return 1;
  }
  // three real roots (p < 0): trigonometric form
  const double m = 2.0 * std::sqrt(-p / 3.0);
  const double c = max_num(-1.0, min_num(1.0, 3.0 * q / (p * m)));
  const double phi = std::acos(c) / 3.0;
  for (int k = 0; k < 3; ++k) out[k] = m * std::cos(phi - 2.0 * M_PI * k / 3.0);
  std::sort(out, out + 3);
  return 3;
}

// The sign change of f in [a, b] (f(a) = fa, f(b) of the other sign) by bisection, to a bracket
// of width tol or `iterations` halvings: its midpoint.
template <typename F>
inline double bisect_sign(const F& f, double a, double b, double fa, double tol, int iterations) {
  for (int it = 0; it < iterations && b - a > tol; ++it) {
    const double mid = 0.5 * (a + b), fm = f(mid);
    if ((fm < 0.0) == (fa < 0.0)) {
      a = mid;
      fa = fm;
    } else {
      b = mid;
    }
  }
  return 0.5 * (a + b);
}

// The first crossing of a torus (major radius R, minor r, about the y axis) with t in (tmin, tmax).
// Along the unit direction from the point of the line nearest the centre, the quartic in s is
// s⁴ + a2 s² + a1 s + a0 (no cubic term) and every root has |s| ≤ R + r; its derivative's roots
// split [-(R + r), R + r] into monotonic pieces, and a sign change in a piece is a root, found by
// bisection. It only chooses: the torus's JAX kernel computes the hit again.
inline double torus_hit(const double* q, const RayD& r, double tmin, double tmax) {
  const double R = std::fabs(q[0]), rr = std::fabs(q[1]);
  const double len = std::sqrt(dot3(r.d, r.d));
  if (!(len > 0.0) || !(R > 0.0) || !(rr > 0.0)) return INFINITY;
  const double u[3] = {r.d[0] / len, r.d[1] / len, r.d[2] / len};
  const double s0 = -dot3(r.o, u);
  const double c[3] = {r.o[0] + s0 * u[0], r.o[1] + s0 * u[1], r.o[2] + s0 * u[2]};
  const double bound = R + rr;
  if (dot3(c, c) > bound * bound) return INFINITY;  // the line misses the bounding sphere
  const double K = dot3(c, c) + R * R - rr * rr, R4 = 4.0 * R * R;
  const double a2 = 2.0 * K - R4 * (u[0] * u[0] + u[2] * u[2]);
  const double a1 = -2.0 * R4 * (c[0] * u[0] + c[2] * u[2]);
  const double a0 = K * K - R4 * (c[0] * c[0] + c[2] * c[2]);
  auto f = [&](double s) { return ((s * s + a2) * s + a1) * s + a0; };
  double cuts[5];
  int n = 0;
  cuts[n++] = -bound * (1.0 + 1e-9);
  double crit[3];
  const int m = cubic_roots(0.5 * a2, 0.25 * a1, crit);  // f' / 4 = s³ + (a2 / 2) s + a1 / 4
  for (int k = 0; k < m; ++k)
    if (crit[k] > cuts[0] && crit[k] < bound * (1.0 + 1e-9)) cuts[n++] = crit[k];
  cuts[n++] = bound * (1.0 + 1e-9);
  for (int k = 0; k + 1 < n; ++k) {
    const double a = cuts[k], b = cuts[k + 1];
    const double fa = f(a), fb = f(b);
    if (fa != 0.0 && fa * fb > 0.0) continue;
    const double root = fa == 0.0 ? a : bisect_sign(f, a, b, fa, 1e-15 * bound, 100);
    const double t = (s0 + root) / len;
    if (t > tmin && t < tmax) return t;
  }
  return INFINITY;
}

// Superellipsoid <e, n> in the unit box: N(x) = ‖(‖(x, y)‖_{2/e}, z)‖_{2/n}, the surface N = 1
// (shapes/_superellipsoid.py, where the JAX kernel computes the hit again). Each p-norm is scaled
// by its larger argument, so no power overflows or underflows to a wrong value.
constexpr double SE_EXPONENT_FLOOR = 1e-4;  // as EXPONENT_FLOOR there

inline double se_pnorm(double a, double b, double p) {
  const double m = std::max(a, b);
  if (!(m > 0.0)) return 0.0;
  return m * std::pow(std::pow(a / m, p) + std::pow(b / m, p), 1.0 / p);
}

// ‖(a, b)‖_p and its partial derivatives (a, b >= 0; an argument at 0 gets 0 where p < 1, whose
// derivative there is infinite: it only decides a slope's sign, and its sign there is that of 0)
inline double se_pnorm_grad(double a, double b, double p, double& da, double& db) {
  const double m = std::max(a, b);
  if (!(m > 0.0)) {
    da = db = (p == 1.0) ? 1.0 : 0.0;
    return 0.0;
  }
  const double ra = a / m, rb = b / m, sum = std::pow(ra, p) + std::pow(rb, p);
  const double k = std::pow(sum, (1.0 - p) / p);  // (m / norm)^(p - 1)
  auto part = [&](double r) { return r > 0.0 ? std::pow(r, p - 1.0) * k : (p == 1.0 ? k : 0.0); };
  da = part(ra);
  db = part(rb);
  return m * std::pow(sum, 1.0 / p);
}

struct SuperEll {
  double ae, an;
  explicit SuperEll(const double* q)
      : ae(2.0 / std::max(q[0], SE_EXPONENT_FLOOR)), an(2.0 / std::max(q[1], SE_EXPONENT_FLOOR)) {}
  double norm(const double* x) const {
    return se_pnorm(se_pnorm(std::fabs(x[0]), std::fabs(x[1]), ae), std::fabs(x[2]), an);
  }
  // N and its derivative along d at x
  double norm_slope(const double* x, const double* d, double& slope) const {
    double dax, day, dnA, dnz;
    const double A = se_pnorm_grad(std::fabs(x[0]), std::fabs(x[1]), ae, dax, day);
    const double n = se_pnorm_grad(A, std::fabs(x[2]), an, dnA, dnz);
    auto sgn = [](double v) { return (v > 0.0) - (v < 0.0); };
    slope = dnA * (dax * sgn(x[0]) * d[0] + day * sgn(x[1]) * d[1]) + dnz * sgn(x[2]) * d[2];
    return n;
  }
};

// The crossings of the line with t in (tmin, tmax): the first, or INFINITY. They are found over the
// line's whole span through the box, whatever tmin is, so asking again from a crossing finds the
// same values and moves past it (a CSG object's members are asked crossing by crossing).
//  * e, n <= 2: N is a norm, convex along the line, so the line crosses at most twice: Newton's
//    method from the span's two ends converges to them without overshooting (the tangent of a
//    convex function stays below it), and a slope that turns before a crossing is a miss.
//  * otherwise as the JAX kernel does it, step by step, so that both find the same crossings: the
//    span cut at the coordinate planes into pieces, each split at its extremum (a sign change of
//    the slope, by bisection between points a thousandth of the piece inside its ends; its middle
//    where the slope keeps its sign), each half cut into four parts; a sign change in a part is a
//    crossing, found by bisection (N is concave in a piece when e, n >= 2, so the halves are
//    monotone; mixed exponents are neither, and a pair of crossings within one part is missed).
inline double superellipsoid_hit(const double* q, const RayD& r, double tmin, double tmax) {
  const double len = std::sqrt(dot3(r.d, r.d));
  if (!(len > 0.0)) return INFINITY;
  double lo = -INFINITY, hi = INFINITY;
  for (int k = 0; k < 3; ++k) {
    if (r.d[k] == 0.0) {
      if (std::fabs(r.o[k]) > 1.0) return INFINITY;
      continue;
    }
    const double a = (-1.0 - r.o[k]) / r.d[k], b = (1.0 - r.o[k]) / r.d[k];
    lo = std::max(lo, std::min(a, b));
    hi = std::min(hi, std::max(a, b));
  }
  if (!(lo <= hi)) return INFINITY;
  const double margin = 1e-3 / len;  // beyond the box, N > 1: both ends lie outside the solid
  lo -= margin;
  hi += margin;
  if (!(lo < tmax) || !(hi > tmin)) return INFINITY;
  const SuperEll se(q);
  auto point = [&](double s, double* x) {
    for (int k = 0; k < 3; ++k) x[k] = r.o[k] + s * r.d[k];
  };
  auto f = [&](double s) {
    double x[3];
    point(s, x);
    return se.norm(x) - 1.0;
  };
  const double tiny = 1e-15 * (std::fabs(lo) + std::fabs(hi) + 1.0 / len);
  if (se.ae >= 1.0 && se.an >= 1.0) {
    double roots[2];
    for (int side = 0; side < 2; ++side) {
      double s = side == 0 ? lo : hi;
      roots[side] = INFINITY;
      for (int it = 0; it < 200; ++it) {
        double x[3], slope;
        point(s, x);
        const double v = se.norm_slope(x, r.d, slope) - 1.0;
        if (v <= 0.0) {
          roots[side] = s;
          break;
        }
        // entering from lo the slope must be negative, leaving towards hi positive
        if (side == 0 ? !(slope < 0.0) : !(slope > 0.0)) break;
        const double step = v / slope;
        s -= step;
        if (std::fabs(step) <= tiny) {
          roots[side] = s;
          break;
        }
      }
      if (side == 0 && !(roots[0] < INFINITY)) return INFINITY;  // a miss
    }
    if (roots[0] > tmin && roots[0] < tmax) return roots[0];
    if (roots[1] > tmin && roots[1] < tmax && roots[1] > roots[0]) return roots[1];
    return INFINITY;
  }
  double knots[5];
  int nk = 0;
  knots[nk++] = lo;
  double cuts[3];
  int nc = 0;
  for (int k = 0; k < 3; ++k) {
    if (r.d[k] == 0.0) continue;
    const double c = -r.o[k] / r.d[k];
    if (c > lo && c < hi) cuts[nc++] = c;
  }
  std::sort(cuts, cuts + nc);
  for (int k = 0; k < nc; ++k) knots[nk++] = cuts[k];
  knots[nk++] = hi;
  const int parts = 4;  // the JAX kernel's _SUBDIVISIONS
  auto slope = [&](double s) {
    double x[3], v;
    point(s, x);
    se.norm_slope(x, r.d, v);
    return v;
  };
  for (int piece = 0; piece + 1 < nk; ++piece) {
    const double a = knots[piece], b = knots[piece + 1];
    // the extremum: the slope's sign change (its bisection as _numerics._bisect does it, a fixed
    // number of halvings), or the middle where the slope keeps its sign
    double x0 = a + 1e-3 * (b - a), x3 = b - 1e-3 * (b - a);
    const double s0 = slope(x0), s3 = slope(x3);
    double c = 0.5 * (a + b);
    if ((s0 <= 0.0) != (s3 < 0.0)) {
      const bool neg = s0 < 0.0;
      for (int it = 0; it < 56; ++it) {
        const double mid = 0.5 * (x0 + x3);
        if ((slope(mid) < 0.0) == neg) {
          x0 = mid;
        } else {
          x3 = mid;
        }
      }
      c = s0 == 0.0 ? a + 1e-3 * (b - a) : s3 == 0.0 ? b - 1e-3 * (b - a) : 0.5 * (x0 + x3);
    }
    const double ends[3] = {a, c, b};
    for (int h = 0; h < 2; ++h) {
      double u = ends[h];
      double fu = f(u);
      for (int j = 1; j <= parts; ++j) {
        const double v = ends[h] + (ends[h + 1] - ends[h]) * j / parts;
        const double fv = f(v);
        if ((fu < 0.0) != (fv < 0.0)) {
          const double t = bisect_sign(f, u, v, fu, tiny, 200);
          if (t > tmin && t < tmax) return t;
          if (t >= tmax) return INFINITY;
        }
        u = v;
        fu = fv;
      }
    }
  }
  return INFINITY;
}

// Q(x) = xᵀ M x + g·x + J of a quadric's coefficients A … J (M symmetric: the cross terms halved)
inline double quadric_value(const double* q, const double* x) {
  return q[0] * x[0] * x[0] + q[1] * x[1] * x[1] + q[2] * x[2] * x[2] + q[3] * x[0] * x[1] + q[4] * x[0] * x[2] +
         q[5] * x[1] * x[2] + q[6] * x[0] + q[7] * x[1] + q[8] * x[2] + q[9];
}

// The first crossing of a quadric with t in (tmin, tmax): the quadratic's roots without
// cancellation, as its JAX kernel (kernels/_numerics.solve_quadratic) finds them, the far root
// dropped where that kernel drops it in its own precision (|a| <= eps |q|: a ray along a
// cylinder's axis), so both see the same crossings.
inline double quadric_hit(const double* q, const RayD& r, double tmin, double tmax, double eps) {
  const double* o = r.o;
  const double* d = r.d;
  const double md[3] = {q[0] * d[0] + 0.5 * q[3] * d[1] + 0.5 * q[4] * d[2],
                        0.5 * q[3] * d[0] + q[1] * d[1] + 0.5 * q[5] * d[2],
                        0.5 * q[4] * d[0] + 0.5 * q[5] * d[1] + q[2] * d[2]};
  const double a = dot3(d, md);
  const double b = 2.0 * dot3(o, md) + q[6] * d[0] + q[7] * d[1] + q[8] * d[2];
  const double c = quadric_value(q, o);
  const double disc = b * b - 4.0 * a * c;
  if (!(disc >= 0.0)) return INFINITY;
  const double sq = std::sqrt(disc);
  const double qq = -0.5 * (b + (b < 0.0 ? -sq : sq));
  const double far = std::fabs(a) > eps * std::fabs(qq) ? qq / a : INFINITY;
  const double near = qq != 0.0 ? c / qq : far;
  const double t0 = std::min(near, far), t1 = std::max(near, far);
  if (t0 > tmin && t0 < tmax) return t0;
  if (t1 > tmin && t1 < tmax) return t1;
  return INFINITY;
}

// ------------------------------------------------------------------------------------ polynomial
// P(x, y, z) = Σ c_ijk x^i y^j z^k of order <= 4 (shapes/_poly.py): 35 coefficients in POV-Ray's
// order (i, then j, then k descending), inside where P < 0. They do not fit an item's 12 numbers:
// a polynomial item takes two rows of parameters, its map and c[0..11] then c[12..34] (and one
// zero); the second row is never named by a program or the hierarchy.
constexpr int POLY_TERMS = 35;

// P at x by Horner's rule in z, then y, then x (the order of the coefficients).
inline double poly_at(const double* c, const double* x) {
  int n = 0;
  double total = 0.0;
  for (int i = 4; i >= 0; --i) {
    double in_yz = 0.0;
    for (int j = 4 - i; j >= 0; --j) {
      double in_z = 0.0;
      for (int k = 4 - i - j; k >= 0; --k) in_z = in_z * x[2] + c[n++];
      in_yz = in_yz * x[1] + in_z;
    }
    total = total * x[0] + in_yz;
  }
  return total;
}

// The coefficients (lowest first) of P(o + s u) as a polynomial in s: the same Horner rule on
// polynomials, each variable the line o_a + s u_a (products truncated at s⁴: P is of order <= 4).
inline void poly_line(const double* c, const double* o, const double* u, double* out) {
  auto times = [](double* p, double a, double b) {
    for (int k = 4; k > 0; --k) p[k] = a * p[k] + b * p[k - 1];
    p[0] *= a;
  };
  int n = 0;
  double total[5] = {0, 0, 0, 0, 0};
  for (int i = 4; i >= 0; --i) {
    double in_yz[5] = {0, 0, 0, 0, 0};
    for (int j = 4 - i; j >= 0; --j) {
      double in_z[5] = {0, 0, 0, 0, 0};
      for (int k = 4 - i - j; k >= 0; --k) {
        times(in_z, o[2], u[2]);
        in_z[0] += c[n++];
      }
      times(in_yz, o[1], u[1]);
      for (int m = 0; m < 5; ++m) in_yz[m] += in_z[m];
    }
    times(total, o[0], u[0]);
    for (int m = 0; m < 5; ++m) total[m] += in_yz[m];
  }
  for (int m = 0; m < 5; ++m) out[m] = total[m];
}

inline double horner1(const double* c, int n, double s) {  // c lowest first, degree n
  double v = c[n];
  for (int k = n - 1; k >= 0; --k) v = v * s + c[k];
  return v;
}

// The root of c (degree n) in [a, b], where it is monotonic and changes sign (f(a) = fa): Newton's
// method kept inside the shrinking bracket (a bisection step where Newton's leaves it), to a bracket
// or a step of width tol.
inline double newton_bisect(const double* c, int n, double a, double b, double fa, double tol) {
  double x = 0.5 * (a + b);
  for (int it = 0; it < 200; ++it) {
    double f = c[n], df = 0.0;
    for (int k = n - 1; k >= 0; --k) {
      df = df * x + f;
      f = f * x + c[k];
    }
    if (f == 0.0) return x;
    if ((f < 0.0) == (fa < 0.0)) {
      a = x;
    } else {
      b = x;
    }
    double next = df != 0.0 ? x - f / df : 0.5 * (a + b);
    if (!(next > a && next < b)) next = 0.5 * (a + b);
    if (std::fabs(next - x) <= tol || b - a <= tol) return next;
    x = next;
  }
  return x;
}

// The real roots in [lo, hi] of the polynomial c (lowest first) of degree <= n, ascending; returns
// how many. The roots of its derivative (found the same way, down to a quadratic's closed form)
// split [lo, hi] into pieces where it is monotonic; a sign change in a piece is a root, found by
// bisection to the last bits. A double root (a tangent ray) that does not change the sign is
// missed, as by the JAX kernel.
inline int poly_roots(const double* c, int n, double lo, double hi, double* out) {
  while (n > 0 && c[n] == 0.0) --n;
  if (n == 0 || !(lo <= hi)) return 0;
  if (n == 1) {
    const double r = -c[0] / c[1];
    if (r >= lo && r <= hi) {
      out[0] = r;
      return 1;
    }
    return 0;
  }
  double crit[4];
  int m = 0;
  if (n == 2) {
    crit[m++] = -0.5 * c[1] / c[2];  // the vertex: the pieces below then hold one root each
  } else {
    double dc[4];
    for (int k = 1; k <= n; ++k) dc[k - 1] = k * c[k];
    m = poly_roots(dc, n - 1, lo, hi, crit);
  }
  double a = lo, fa = horner1(c, n, lo);
  int count = 0;
  const double tol = 4.0 * std::numeric_limits<double>::epsilon() * std::max(std::fabs(lo), std::fabs(hi));
  for (int piece = 0; piece <= m; ++piece) {
    const double b = piece < m ? std::min(std::max(crit[piece], a), hi) : hi;
    const double fb = horner1(c, n, b);
    if (fa == 0.0) {
      if (count == 0 || out[count - 1] < a) out[count++] = a;
    } else if ((fa < 0.0) != (fb < 0.0) && fb != 0.0) {
      out[count++] = newton_bisect(c, n, a, b, fa, tol);
    }
    a = b;
    fa = fb;
  }
  if (fa == 0.0 && (count == 0 || out[count - 1] < a)) out[count++] = a;
  return count;
}

// Fujiwara's bound on the moduli of the roots of c (lowest first, degree n, c[n] != 0).
inline double fujiwara(const double* c, int n) {
  double bound = 0.0;
  for (int k = 1; k < n; ++k) bound = std::max(bound, std::pow(std::fabs(c[n - k] / c[n]), 1.0 / k));
  bound = std::max(bound, std::pow(std::fabs(c[0] / (2.0 * c[n])), 1.0 / n));
  return 2.0 * bound;
}

// The first crossing of P = 0 with t in (tmin, tmax): the roots along the unit direction from the
// point of the line nearest the object's origin (the JAX kernel's well-scaled frame), all of them
// within Fujiwara's bound (at most S_MAX, as there), whatever tmin is: the crossings a CSG unit
// walks through one by one come out the same each time.
// Every crossing t of P = 0 (ascending, at most 4; see poly_hit); returns how many.
inline int poly_crossings(const double* c, const RayD& r, double* ts) {
  constexpr double S_MAX = 1e7;  // as shapes/_poly.S_MAX
  const double len = std::sqrt(dot3(r.d, r.d));
  if (!(len > 0.0)) return 0;
  const double u[3] = {r.d[0] / len, r.d[1] / len, r.d[2] / len};
  const double s0 = -dot3(r.o, u);
  const double oc[3] = {r.o[0] + s0 * u[0], r.o[1] + s0 * u[1], r.o[2] + s0 * u[2]};
  double line[5];
  poly_line(c, oc, u, line);
  int n = 4;
  while (n > 0 && line[n] == 0.0) --n;
  if (n == 0) return 0;
  const double bound = std::min(fujiwara(line, n) * 1.001, S_MAX);
  const int count = poly_roots(line, n, -bound, bound, ts);
  for (int k = 0; k < count; ++k) ts[k] = (s0 + ts[k]) / len;
  return count;
}

inline double poly_hit(const double* c, const RayD& r, double tmin, double tmax) {
  double ts[4];
  const int count = poly_crossings(c, r, ts);
  for (int k = 0; k < count; ++k)
    if (ts[k] > tmin && ts[k] < tmax) return ts[k];
  return INFINITY;
}

// ------------------------------------------------------------------------------------ prism
// A swept outline (shapes/_prism.py): S segments of Bernstein degree n (1-3) in the x-z plane,
// swept along y between two heights, straight or conic (the outline scaled by the height). Its
// item takes several rows: the map, then the header [S, n, conic, open, h1, h2, axis] (axis 2:
// text, swept along z), then from params[24] each segment's n + 1 control points (x, z) and then
// the S senses (0: a padding segment). The rows after the first are items of kind KIND_NONE.
template <typename T>
struct PrismD {
  int S, n;
  bool conic, open;
  double lo, hi;
  const T* c;      // S * (n + 1) * 2: segment k's control point j is (c[2 (m k + j)], c[… + 1])
  const T* sense;  // S
};

// The Bernstein polynomial w[0..n] at s (de Casteljau).
inline double bern(const double* w, int n, double s) {
  double b[4];
  for (int k = 0; k <= n; ++k) b[k] = w[k];
  for (int m = n; m > 0; --m)
    for (int k = 0; k < m; ++k) b[k] += s * (b[k + 1] - b[k]);
  return b[0];
}

// The roots of w in [0, 1), half-open at the ends as the JAX kernel's (a zero at a joint counts
// for one of the two segments): the pieces between the critical points, a sign change in each
// found by bisection. Returns how many (at most n).
inline int bern_roots(const double* w, int n, double* out) {
  double split[4] = {0.0, 1.0, 1.0, 1.0};
  int pieces = 1;
  if (n >= 2) {  // the derivative's roots in (0, 1)
    double dw[3];
    for (int k = 0; k < n; ++k) dw[k] = n * (w[k + 1] - w[k]);
    double cr[2];
    int nc = 0;
    if (n == 2) {
      const double den = dw[0] - dw[1];
      if (den != 0.0) cr[nc++] = dw[0] / den;
    } else {  // a quadratic in power form
      const double a = dw[0] - 2.0 * dw[1] + dw[2], b = 2.0 * (dw[1] - dw[0]), c = dw[0];
      if (std::fabs(a) > 1e-300) {
        const double disc = b * b - 4.0 * a * c;
        if (disc >= 0.0) {
          const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
          if (q != 0.0) cr[nc++] = c / q;
          cr[nc++] = q / a;
        }
      } else if (b != 0.0) {
        cr[nc++] = -c / b;
      }
    }
    std::sort(cr, cr + nc);
    for (int k = 0; k < nc; ++k)
      if (cr[k] > split[pieces - 1] && cr[k] < 1.0) split[pieces++] = cr[k];
    split[pieces] = 1.0;
  }
  int count = 0;
  double fa = w[0];
  for (int k = 0; k < pieces; ++k) {
    const double a = split[k], b = split[k + 1];
    const double fb = (k == pieces - 1) ? w[n] : bern(w, n, b);
    if ((fa > 0.0) != (fb > 0.0)) {
      auto f = [&](double s) { return bern(w, n, s); };
      out[count++] = bisect_sign(f, a, b, fa, 1e-15, 64);
    }
    fa = fb;
  }
  return count;
}

// Whether (x, z) is filled (even-odd: crossings of the half-line towards +x).
template <typename T>
inline bool prism_filled(const PrismD<T>& P, double x, double z) {
  int crossings = 0;
  const int m = P.n + 1;
  for (int k = 0; k < P.S; ++k) {
    if (P.sense[k] == 0) continue;
    const T* c = P.c + 2 * m * k;
    double gz[4], gx[4];
    double x_max = -INFINITY;
    bool below = false, above = false;
    for (int j = 0; j < m; ++j) {
      gx[j] = static_cast<double>(c[2 * j]);
      gz[j] = static_cast<double>(c[2 * j + 1]) - z;
      x_max = std::max(x_max, gx[j]);
      below |= gz[j] <= 0.0;
      above |= gz[j] > 0.0;
    }
    // the curve lies in its control points' hull: no crossing of the half-line where they all
    // lie on one side of its line or behind its start
    if (!(below && above) || !(x_max > x)) continue;
    double s[3];
    const int count = bern_roots(gz, P.n, s);
    for (int j = 0; j < count; ++j)
      if (bern(gx, P.n, s[j]) > x) ++crossings;
  }
  return crossings % 2 == 1;
}

template <typename T>
inline PrismD<T> prism_of(const T* params) {
  PrismD<T> P;
  P.S = static_cast<int>(params[12]);
  P.n = static_cast<int>(params[13]);
  P.conic = params[14] != 0;
  P.open = params[15] != 0;
  P.lo = std::min<double>(params[16], params[17]);
  P.hi = std::max<double>(params[16], params[17]);
  P.c = params + 24;
  P.sense = params + 24 + P.S * 2 * (P.n + 1);
  return P;
}

// The first crossing of the prism with t in (tmin, tmax), the ray in object space (its axes
// swapped for text).
template <typename T>
inline double prism_hit(const PrismD<T>& P, const RayD& r, double tmin, double tmax) {
  double best = tmax;
  const int m = P.n + 1;
  for (int k = 0; k < P.S; ++k) {
    if (P.sense[k] == 0) continue;
    double cx[4], cz[4];
    for (int i = 0; i < m; ++i) {
      cx[i] = static_cast<double>(P.c[2 * (m * k + i)]);
      cz[i] = static_cast<double>(P.c[2 * (m * k + i) + 1]);
    }
    if (!P.conic) {  // the projected line misses the hull of the control points: no wall crossing
      double lo_x = cx[0], hi_x = cx[0], lo_z = cz[0], hi_z = cz[0];
      for (int i = 1; i < m; ++i) {
        lo_x = std::min(lo_x, cx[i]);
        hi_x = std::max(hi_x, cx[i]);
        lo_z = std::min(lo_z, cz[i]);
        hi_z = std::max(hi_z, cz[i]);
      }
      const double e0 = r.d[0] * (lo_z - r.o[2]) - r.d[2] * (lo_x - r.o[0]);
      const double e1 = r.d[0] * (lo_z - r.o[2]) - r.d[2] * (hi_x - r.o[0]);
      const double e2 = r.d[0] * (hi_z - r.o[2]) - r.d[2] * (lo_x - r.o[0]);
      const double e3 = r.d[0] * (hi_z - r.o[2]) - r.d[2] * (hi_x - r.o[0]);
      if ((e0 > 0 && e1 > 0 && e2 > 0 && e3 > 0) || (e0 < 0 && e1 < 0 && e2 < 0 && e3 < 0)) continue;
    }
    double w[4];
    double mx = 0, my = 0, mz = 0;
    if (P.conic) {
      mx = r.o[1] * r.d[2] - r.o[2] * r.d[1];
      my = r.o[2] * r.d[0] - r.o[0] * r.d[2];
      mz = r.o[0] * r.d[1] - r.o[1] * r.d[0];
    }
    for (int j = 0; j < m; ++j) {
      const double x = cx[j], z = cz[j];
      w[j] = P.conic ? mx * x + mz * z + my : r.d[0] * (z - r.o[2]) - r.d[2] * (x - r.o[0]);
    }
    double s[3];
    const int count = bern_roots(w, P.n, s);
    for (int j = 0; j < count; ++j) {
      const double x = bern(cx, P.n, s[j]), z = bern(cz, P.n, s[j]);
      double t;
      if (P.conic) {
        const double v[3] = {x, 1.0, z};
        const double dv[3] = {r.d[1] * v[2] - r.d[2] * v[1], r.d[2] * v[0] - r.d[0] * v[2], r.d[0] * v[1] - r.d[1] * v[0]};
        const double ov[3] = {r.o[1] * v[2] - r.o[2] * v[1], r.o[2] * v[0] - r.o[0] * v[2], r.o[0] * v[1] - r.o[1] * v[0]};
        const double dd = dot3(dv, dv);
        if (!(dd > 0.0)) continue;
        t = -dot3(ov, dv) / dd;
      } else {
        const double dd = r.d[0] * r.d[0] + r.d[2] * r.d[2];
        if (!(dd > 0.0)) continue;
        t = ((x - r.o[0]) * r.d[0] + (z - r.o[2]) * r.d[2]) / dd;
      }
      const double y = r.o[1] + t * r.d[1];
      if (y >= P.lo && y <= P.hi) keep_first(t, tmin, best);
    }
  }
  if (!P.open && r.d[1] != 0.0) {
    for (double h : {P.lo, P.hi}) {
      const double t = (h - r.o[1]) / r.d[1];
      if (!(t > tmin && t < best)) continue;
      const double scale = P.conic ? h : 1.0;
      if (scale == 0.0) continue;
      if (prism_filled(P, (r.o[0] + t * r.d[0]) / scale, (r.o[2] + t * r.d[2]) / scale)) best = t;
    }
  }
  return best < tmax ? best : INFINITY;
}

// ------------------------------------------------------------------------------------ lathe
// A curve (r(s), y(s)) of S Bernstein segments turned about the y axis (shapes/_lathe.py), laid
// out as a prism's item (prism_of: no heights, no caps). A line is at distance ρ(t) from the
// axis, ρ² = a t² + 2 b t + c; it reaches the radius r(s) at t_lo(s) ≤ t_hi(s), and crosses the
// surface where on either branch g(s) = y(s) − o_y − d_y t(s) vanishes. Each segment is cut where
// the line's nearest approach to the axis equals r(s) (the branches meet there), each piece's
// branches sampled at LATHE_SAMPLES + 1 points and each sign change bisected: the JAX kernel's
// method, in double.
constexpr int LATHE_SAMPLES = 16;

struct LatheLine {
  double a, b, c, oy, dy;
  bool axial;  // the line runs along the axis: r(s)² = c, t from the height
};

// g and t of branch j (0: the near root, 1: the far) at the curve point (rs, ys); false where the
// line does not reach the radius (``pinch``: taken as the branches' meeting point).
inline bool lathe_branch(const LatheLine& L, double rs, double ys, int j, bool pinch, double& g, double& t) {
  const double cc = L.c - rs * rs;
  if (L.axial) {
    if (j == 1) return false;
    g = -cc;
    t = L.dy != 0.0 ? (ys - L.oy) / L.dy : INFINITY;
    return true;
  }
  double disc = L.b * L.b - L.a * cc;
  if (pinch) disc = 0.0;
  const bool reached = disc >= 0.0;
  const double sq = disc > 0.0 ? std::sqrt(disc) : 0.0;
  const double q = -(L.b + (L.b < 0 ? -sq : sq));
  const double far_t = q / L.a;
  const double near_t = (q != 0.0 && disc > 0.0) ? cc / q : far_t;
  t = j == 0 ? std::min(far_t, near_t) : std::max(far_t, near_t);
  g = ys - L.oy - L.dy * t;
  return reached;
}

template <typename T>
inline double lathe_hit(const PrismD<T>& P, const RayD& r, double tmin, double tmax) {
  double best = tmax;
  const int m = P.n + 1;
  LatheLine L;
  L.a = r.d[0] * r.d[0] + r.d[2] * r.d[2];
  L.b = r.o[0] * r.d[0] + r.o[2] * r.d[2];
  L.c = r.o[0] * r.o[0] + r.o[2] * r.o[2];
  L.oy = r.o[1];
  L.dy = r.d[1];
  L.axial = L.a <= 1e-6 * (L.a + L.dy * L.dy);
  const double rho_min = L.axial ? 0.0 : std::sqrt(std::max(0.0, (L.a * L.c - L.b * L.b) / L.a));
  for (int k = 0; k < P.S; ++k) {
    if (P.sense[k] == 0) continue;
    double cr[4], cy[4], w[4];
    double r_min = INFINITY, r_max = 0.0, y_lo = INFINITY, y_hi = -INFINITY;
    for (int i = 0; i < m; ++i) {
      cr[i] = static_cast<double>(P.c[2 * (m * k + i)]);
      cy[i] = static_cast<double>(P.c[2 * (m * k + i) + 1]);
      w[i] = cr[i] - rho_min;
      r_min = std::min(r_min, std::max(cr[i], 0.0));
      r_max = std::max(r_max, std::fabs(cr[i]));
      y_lo = std::min(y_lo, cy[i]);
      y_hi = std::max(y_hi, cy[i]);
    }
    // the curve lies in its control points' hull: a line that stays farther from the axis than
    // the hull's radius, or above or below it, misses the segment; so does one whose stretch
    // within the hull's heights lies beyond the crossing found, or runs outside its radii there
    if (!L.axial && rho_min > r_max) continue;
    if (L.dy == 0.0 && (L.oy < y_lo || L.oy > y_hi)) continue;
    if (L.dy != 0.0) {
      const double ta = (y_lo - L.oy) / L.dy, tb = (y_hi - L.oy) / L.dy;
      const double t1 = std::min(ta, tb), t2 = std::max(ta, tb);
      if (t2 <= tmin || t1 >= best) continue;
      if (!L.axial) {
        auto rho2 = [&](double t) { return (L.a * t + 2.0 * L.b) * t + L.c; };
        const double vertex = -L.b / L.a;
        const double lo2 = (vertex > t1 && vertex < t2) ? rho_min * rho_min : std::min(rho2(t1), rho2(t2));
        const double hi2 = std::max(rho2(t1), rho2(t2));
        if (lo2 > r_max * r_max * (1.0 + 1e-9) || hi2 < r_min * r_min * (1.0 - 1e-9)) continue;
      }
    }
    double ends[5];
    int count = 1;
    ends[0] = 0.0;
    if (!L.axial) {
      double junction[3];
      const int nj = bern_roots(w, P.n, junction);
      for (int j = 0; j < nj; ++j) ends[count++] = junction[j];
    }
    const int first_junction = 1, last_junction = count - 1;
    ends[count++] = 1.0;
    std::sort(ends, ends + count);
    for (int piece = 0; piece + 1 < count; ++piece) {
      const double s0 = ends[piece], s1 = ends[piece + 1];
      if (!(s1 > s0)) continue;
      const bool pinch0 = !L.axial && piece >= first_junction && piece <= last_junction;
      const bool pinch1 = !L.axial && piece + 1 >= first_junction && piece + 1 <= last_junction;
      double g, t;
      const double mid = 0.5 * (s0 + s1);
      if (!lathe_branch(L, bern(cr, P.n, mid), bern(cy, P.n, mid), 0, false, g, t)) continue;
      for (int j = 0; j < 2; ++j) {
        if (L.axial && j == 1) break;
        auto gj = [&](double s, bool pinch) {
          double gv, tv;
          lathe_branch(L, bern(cr, P.n, s), bern(cy, P.n, s), j, pinch, gv, tv);
          return gv;
        };
        double sa = s0, ga = gj(s0, pinch0);
        for (int q = 1; q <= LATHE_SAMPLES; ++q) {
          const double sb = q == LATHE_SAMPLES ? s1 : s0 + (s1 - s0) * q / LATHE_SAMPLES;
          const double gb = gj(sb, q == LATHE_SAMPLES && pinch1);
          if ((ga > 0.0) != (gb > 0.0)) {
            auto f = [&](double s) { return gj(s, false); };
            const double s = ga == 0.0 ? sa : bisect_sign(f, sa, sb, ga, 1e-15, 64);
            double gv, tv;
            if (lathe_branch(L, bern(cr, P.n, s), bern(cy, P.n, s), j, false, gv, tv)) {
              if (!L.axial && L.dy != 0.0) {  // the better conditioned of the two ways to t
                const double rs = bern(cr, P.n, s);
                double dr[3], dyc[3];
                for (int i = 0; i < P.n; ++i) {
                  dr[i] = P.n * (cr[i + 1] - cr[i]);
                  dyc[i] = P.n * (cy[i + 1] - cy[i]);
                }
                const double disc = L.b * L.b - L.a * (L.c - rs * rs);
                const double slope_r = P.n > 0 ? bern(dr, P.n - 1, s) : 0.0;
                const double slope_y = P.n > 0 ? bern(dyc, P.n - 1, s) : 0.0;
                if (std::fabs(slope_y) * std::sqrt(std::max(disc, 0.0)) < std::fabs(L.dy) * std::fabs(rs * slope_r))
                  tv = (bern(cy, P.n, s) - L.oy) / L.dy;
              }
              keep_first(tv, tmin, best);
            }
          }
          sa = sb;
          ga = gb;
        }
      }
    }
  }
  return best < tmax ? best : INFINITY;
}

// ------------------------------------------------------------------------------------ blob
// Components' fields summed (shapes/_blob.py): params[12] = N, params[13] = the threshold, and
// from params + 24 each component's BLOB_STRIDE numbers: strength, r², the map of the blob's
// space into the component's (3×3 row-major, then its offset: q = M p + m, from the axis's first
// end), the axis's unit direction and length (0: a sphere). Along the line each component's field
// is a quartic of the line's parameter on its pieces' intervals (caps and body); between
// consecutive ends of those intervals the field is one quartic, expanded about the segment's
// middle from the pieces covering it and solved there (its turning points split it into
// monotone pieces, each bisected): the JAX kernel's method, with every piece at once.
constexpr int BLOB_STRIDE = 18;

struct BlobPiece {
  double lo, hi, s, r2;
  double P[3], V[3];
};

// s where lo <= u0 + s u1 <= hi, intersected into [a, b]; false where empty.
inline bool blob_slab(double u0, double u1, double lo, double hi, double& a, double& b) {
  if (u1 == 0.0) return u0 >= lo && u0 <= hi;
  double x = (lo - u0) / u1, y = (hi - u0) / u1;
  if (x > y) std::swap(x, y);
  a = std::max(a, x);
  b = std::min(b, y);
  return a < b;
}

template <typename T>
inline double blob_field(const T* params, const double* x) {
  const int n = static_cast<int>(params[12]);
  double total = 0.0;
  for (int k = 0; k < n; ++k) {
    const T* c = params + 24 + BLOB_STRIDE * k;
    const double s = c[0], r2 = c[1];
    if (s == 0.0 || !(r2 > 0.0)) continue;
    double q[3];
    for (int i = 0; i < 3; ++i)
      q[i] = c[2 + 3 * i] * x[0] + c[3 + 3 * i] * x[1] + c[4 + 3 * i] * x[2] + c[11 + i];
    const double len = c[17];
    const double u = std::min(std::max(q[0] * c[14] + q[1] * c[15] + q[2] * c[16], 0.0), len);
    for (int i = 0; i < 3; ++i) q[i] -= u * c[14 + i];
    const double ratio = dot3(q, q) / r2;
    if (ratio < 1.0) total += s * (1.0 - ratio) * (1.0 - ratio);
  }
  return total;
}

// The roots of the quartic c[0] s⁴ + … + c[4] in [a, b) in ascending order; returns how many.
inline int quartic_roots_in(const double* c, double a, double b, double* out) {
  auto f = [&](double s) { return (((c[0] * s + c[1]) * s + c[2]) * s + c[3]) * s + c[4]; };
  auto f1 = [&](double s) { return ((4.0 * c[0] * s + 3.0 * c[1]) * s + 2.0 * c[2]) * s + c[3]; };
  // p'' = 12 c0 s² + 6 c1 s + 2 c2: its roots split [a, b] into pieces where p' is monotone
  double cuts[4];
  int nc = 0;
  const double qa = 12.0 * c[0], qb = 6.0 * c[1], qc = 2.0 * c[2];
  if (qa != 0.0) {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc > 0.0) {
      const double qq = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
      double r1 = qq / qa, r2 = qq != 0.0 ? qc / qq : r1;
      if (r1 > r2) std::swap(r1, r2);
      if (r1 > a && r1 < b) cuts[nc++] = r1;
      if (r2 > a && r2 < b && r2 != r1) cuts[nc++] = r2;
    }
  } else if (qb != 0.0) {
    const double r1 = -qc / qb;
    if (r1 > a && r1 < b) cuts[nc++] = r1;
  }
  double turns[6];
  int nt = 0;
  turns[nt++] = a;
  double lo = a;
  for (int k = 0; k <= nc; ++k) {
    const double hi = k < nc ? cuts[k] : b;
    const double flo = f1(lo), fhi = f1(hi);
    if (flo != 0.0 && (flo < 0.0) != (fhi < 0.0)) turns[nt++] = bisect_sign(f1, lo, hi, flo, 0.0, 64);
    lo = hi;
  }
  turns[nt++] = b;
  int n = 0;
  for (int k = 0; k + 1 < nt; ++k) {
    const double x0 = turns[k], x1 = turns[k + 1];
    if (!(x1 > x0)) continue;
    const double f0 = f(x0), fx = f(x1);
    if (f0 == 0.0) {
      out[n++] = x0;
    } else if ((f0 < 0.0) != (fx < 0.0) && fx != 0.0) {
      out[n++] = bisect_sign(f, x0, x1, f0, 0.0, 64);
    }
  }
  return n;
}

template <typename T>
inline double blob_hit(const T* params, const RayD& r, double tmin, double tmax) {
  const int n = static_cast<int>(params[12]);
  const double threshold = params[13];
  const double len = std::sqrt(dot3(r.d, r.d));
  if (!(len > 0.0) || n <= 0) return INFINITY;
  const double u[3] = {r.d[0] / len, r.d[1] / len, r.d[2] / len};
  const double s_min = tmin * len, s_max = std::isfinite(tmax) ? tmax * len : INFINITY;
  thread_local std::vector<BlobPiece> pieces;
  thread_local std::vector<std::pair<double, int>> events;
  pieces.clear();
  for (int k = 0; k < n; ++k) {
    const T* c = params + 24 + BLOB_STRIDE * k;
    const double s = c[0], r2 = c[1];
    if (s == 0.0 || !(r2 > 0.0)) continue;
    double P[3], V[3];
    for (int i = 0; i < 3; ++i) {
      P[i] = c[2 + 3 * i] * r.o[0] + c[3 + 3 * i] * r.o[1] + c[4 + 3 * i] * r.o[2] + c[11 + i];
      V[i] = c[2 + 3 * i] * u[0] + c[3 + 3 * i] * u[1] + c[4 + 3 * i] * u[2];
    }
    const double ax[3] = {c[14], c[15], c[16]}, length = c[17];
    const double u0 = dot3(P, ax), u1 = dot3(V, ax);
    for (int part = 0; part < (length > 0.0 ? 3 : 1); ++part) {
      BlobPiece pc;
      pc.s = s;
      pc.r2 = r2;
      for (int i = 0; i < 3; ++i) {
        pc.P[i] = part == 1 ? P[i] - u0 * ax[i] : part == 2 ? P[i] - length * ax[i] : P[i];
        pc.V[i] = part == 1 ? V[i] - u1 * ax[i] : V[i];
      }
      double a = s_min, b = s_max;
      if (length > 0.0) {
        const double lo = part == 0 ? -INFINITY : part == 1 ? 0.0 : length;
        const double hi = part == 0 ? 0.0 : part == 1 ? length : INFINITY;
        if (!blob_slab(u0, u1, lo, hi, a, b)) continue;
      }
      // where |P + s V|² < r²
      const double vv = dot3(pc.V, pc.V);
      if (vv > 0.0) {
        const double mid = -dot3(pc.P, pc.V) / vv;
        double f[3];
        for (int i = 0; i < 3; ++i) f[i] = pc.P[i] + mid * pc.V[i];
        const double room = r2 - dot3(f, f);
        if (!(room > 0.0)) continue;
        const double half = std::sqrt(room / vv);
        a = std::max(a, mid - half);
        b = std::min(b, mid + half);
      } else if (!(dot3(pc.P, pc.P) < r2)) {
        continue;
      }
      if (!(a < b)) continue;
      pc.lo = a;
      pc.hi = b;
      pieces.push_back(pc);
    }
  }
  if (pieces.empty()) return INFINITY;
  events.clear();
  for (int k = 0; k < static_cast<int>(pieces.size()); ++k) {
    events.emplace_back(pieces[k].lo, k + 1);
    events.emplace_back(pieces[k].hi, -(k + 1));
  }
  std::sort(events.begin(), events.end());
  thread_local std::vector<int> active;
  active.clear();
  for (size_t e = 0; e + 1 < events.size(); ++e) {
    const int id = events[e].second;
    if (id > 0) {
      active.push_back(id - 1);
    } else {
      active.erase(std::find(active.begin(), active.end(), -id - 1));
    }
    const double a = events[e].first, b = events[e + 1].first;
    if (!(b > a) || active.empty()) continue;
    const double mid = 0.5 * (a + b), half = 0.5 * (b - a);
    double c[5] = {0.0, 0.0, 0.0, 0.0, -threshold};
    double top = 0.0;
    for (int k : active) {
      const BlobPiece& pc = pieces[k];
      double P[3];
      for (int i = 0; i < 3; ++i) P[i] = pc.P[i] + mid * pc.V[i];
      const double qa = half * half * dot3(pc.V, pc.V) / pc.r2, qb = 2.0 * half * dot3(P, pc.V) / pc.r2;
      const double qc = dot3(P, P) / pc.r2;
      c[0] += pc.s * qa * qa;
      c[1] += pc.s * 2.0 * qa * qb;
      c[2] += pc.s * (qb * qb + 2.0 * qa * qc - 2.0 * qa);
      c[3] += pc.s * (2.0 * qb * qc - 2.0 * qb);
      c[4] += pc.s * (qc * qc - 2.0 * qc + 1.0);
      top += std::max(pc.s, 0.0);
    }
    if (top < threshold) continue;  // the field here cannot reach the threshold
    double roots[4];
    const int nr = quartic_roots_in(c, -1.0, 1.0, roots);
    for (int k = 0; k < nr; ++k) {
      const double t = (mid + roots[k] * half) / len;
      if (t > tmin && t < tmax) return t;
    }
  }
  return INFINITY;
}

// The 35 coefficients of a polynomial item (its two rows: see above), in double.
template <typename T>
inline void poly_coefficients(const T* params, double* c) {
  for (int k = 0; k < POLY_TERMS; ++k) c[k] = static_cast<double>(params[12 + k]);
}

// The first crossing of the item with t in (tmin, tmax), or INFINITY.
template <typename T>
inline double item_hit(int32_t kind, const T* params, const double* o, const double* d, double tmin,
                       double tmax) {
  double p[ITEM_PARAMS];
  for (int k = 0; k < ITEM_PARAMS; ++k) p[k] = static_cast<double>(params[k]);
  RayD r = to_object(p, o, d);
  if (kind == KIND_POLY) {
    double c[POLY_TERMS];
    poly_coefficients(params, c);
    return poly_hit(c, r, tmin, tmax);
  }
  if (kind == KIND_PRISM) {
    const PrismD<T> P = prism_of(params);
    if (static_cast<int>(params[18]) == 2) {
      std::swap(r.o[1], r.o[2]);
      std::swap(r.d[1], r.d[2]);
    }
    return prism_hit(P, r, tmin, tmax);
  }
  if (kind == KIND_LATHE) return lathe_hit(prism_of(params), r, tmin, tmax);
  if (kind == KIND_BLOB) return blob_hit(params, r, tmin, tmax);
  const double* q = p + 12;
  double t0 = INFINITY, t1 = INFINITY;
  if (kind == KIND_SPHERE) {
    double oc[3] = {r.o[0] - q[0], r.o[1] - q[1], r.o[2] - q[2]};
    double a = dot3(r.d, r.d);
    if (!(a > 0.0)) return INFINITY;
    // distance of the line from the centre, computed from the foot of the perpendicular (stable)
    double tc = -dot3(oc, r.d) / a;
    double f[3] = {oc[0] + tc * r.d[0], oc[1] + tc * r.d[1], oc[2] + tc * r.d[2]};
    double h2 = q[3] * q[3] - dot3(f, f);
    if (h2 < 0.0 || !(q[3] > 0.0)) return INFINITY;  // a radius <= 0 has no surface (as POV-Ray)
    double h = std::sqrt(h2 / a);
    t0 = tc - h;
    t1 = tc + h;
  } else if (kind == KIND_BOX) {
    double tn = -INFINITY, tf = INFINITY;
    for (int k = 0; k < 3; ++k) {
      double lo = std::min(q[k], q[3 + k]), hi = std::max(q[k], q[3 + k]);
      if (r.d[k] == 0.0) {
        if (r.o[k] < lo || r.o[k] > hi) return INFINITY;
        continue;
      }
      double inv = 1.0 / r.d[k];
      double a = (lo - r.o[k]) * inv, b = (hi - r.o[k]) * inv;
      tn = std::max(tn, std::min(a, b));
      tf = std::min(tf, std::max(a, b));
    }
    if (!(tn <= tf)) return INFINITY;
    t0 = tn;
    t1 = tf;
  } else if (kind == KIND_TRIANGLE) {
    const double *p1 = q, *p2 = q + 3, *p3 = q + 6;
    double e1[3] = {p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]};
    double e2[3] = {p3[0] - p1[0], p3[1] - p1[1], p3[2] - p1[2]};
    double pv[3] = {r.d[1] * e2[2] - r.d[2] * e2[1], r.d[2] * e2[0] - r.d[0] * e2[2],
                    r.d[0] * e2[1] - r.d[1] * e2[0]};
    double det = dot3(e1, pv);
    if (det == 0.0 || !std::isfinite(det)) return INFINITY;
    double inv = 1.0 / det;
    double s[3] = {r.o[0] - p1[0], r.o[1] - p1[1], r.o[2] - p1[2]};
    double u = dot3(s, pv) * inv;
    // a hair of tolerance on the edges: the JAX kernel decides the exact hit of the chosen item
    const double tol = 1e-9;
    if (u < -tol || u > 1.0 + tol) return INFINITY;
    double qv[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
    double v = dot3(r.d, qv) * inv;
    if (v < -tol || u + v > 1.0 + tol) return INFINITY;
    t0 = dot3(e2, qv) * inv;
  } else if (kind == KIND_FRUSTUM) {
    return frustum_hit(q, r, tmin, tmax);
  } else if (kind == KIND_TORUS) {
    return torus_hit(q, r, tmin, tmax);
  } else if (kind == KIND_SUPERELLIPSOID) {
    return superellipsoid_hit(q, r, tmin, tmax);
  } else if (kind == KIND_QUADRIC) {
    return quadric_hit(q, r, tmin, tmax, static_cast<double>(std::numeric_limits<T>::epsilon()));
  } else if (kind == KIND_DISC) {
    double n[3] = {q[3], q[4], q[5]};
    double nn = std::sqrt(dot3(n, n));
    if (!(nn > 0.0)) return INFINITY;
    double l[3] = {r.o[0] - q[0], r.o[1] - q[1], r.o[2] - q[2]};
    double dn = dot3(n, r.d) / nn, ln = dot3(n, l) / nn;
    if (dn == 0.0) return INFINITY;
    double t = -ln / dn;
    double p[3] = {l[0] + t * r.d[0], l[1] + t * r.d[1], l[2] + t * r.d[2]};
    double rho2 = dot3(p, p);
    if (rho2 > q[6] * q[6] || rho2 < q[7] * q[7]) return INFINITY;
    t0 = t;
  } else if (kind == KIND_PLANE) {
    const double nn = std::sqrt(dot3(q, q)), dn = dot3(q, r.d);
    if (dn == 0.0 || !(nn > 0.0)) return INFINITY;
    t0 = (q[3] * nn - dot3(q, r.o)) / dn;
  } else {
    return INFINITY;
  }
  if (t0 > tmin && t0 < tmax) return t0;
  if (t1 > tmin && t1 < tmax) return t1;
  return INFINITY;
}

// Whether the world point p is strictly inside the item's solid (POV-Ray's inside tests, as the
// shapes' JAX `inside`): the half-space behind a disc or a plane, the solid of an open cylinder;
// a triangle has no inside.
template <typename T>
inline bool item_inside(int32_t kind, const T* params, const double* pw) {
  double p[ITEM_PARAMS];
  for (int k = 0; k < ITEM_PARAMS; ++k) p[k] = static_cast<double>(params[k]);
  double x[3];
  for (int i = 0; i < 3; ++i) x[i] = p[4 * i] * pw[0] + p[4 * i + 1] * pw[1] + p[4 * i + 2] * pw[2] + p[4 * i + 3];
  const double* q = p + 12;
  if (kind == KIND_SPHERE) {
    const double l[3] = {x[0] - q[0], x[1] - q[1], x[2] - q[2]};
    return q[3] > 0.0 && dot3(l, l) < q[3] * q[3];
  }
  if (kind == KIND_BOX) {
    for (int k = 0; k < 3; ++k) {
      const double lo = std::min(q[k], q[3 + k]), hi = std::max(q[k], q[3 + k]);
      if (!(x[k] > lo && x[k] < hi)) return false;
    }
    return true;
  }
  if (kind == KIND_FRUSTUM) {
    const double *base = q, *cap = q + 4;
    double axis[3] = {cap[0] - base[0], cap[1] - base[1], cap[2] - base[2]};
    const double length = std::sqrt(dot3(axis, axis));
    if (!(length > 0.0)) return false;
    for (double& a : axis) a /= length;
    const double l[3] = {x[0] - base[0], x[1] - base[1], x[2] - base[2]};
    const double h = dot3(l, axis);
    const double lp[3] = {l[0] - h * axis[0], l[1] - h * axis[1], l[2] - h * axis[2]};
    const double rad = q[3] + (q[7] - q[3]) / length * h;
    return h > 0.0 && h < length && dot3(lp, lp) < rad * rad;
  }
  if (kind == KIND_DISC) {
    const double nn = std::sqrt(dot3(q + 3, q + 3));
    const double l[3] = {x[0] - q[0], x[1] - q[1], x[2] - q[2]};
    return nn > 0.0 && dot3(q + 3, l) / nn < 0.0;
  }
  if (kind == KIND_TORUS) {  // the factored quartic (its sign, well conditioned near the surface)
    const double R = q[0], r = q[1];
    const double rho = std::sqrt(x[0] * x[0] + x[2] * x[2]);
    const double a = (rho - R) * (rho - R) + x[1] * x[1] - r * r;
    const double b = (rho + R) * (rho + R) + x[1] * x[1] - r * r;
    return a * b < 0.0;
  }
  if (kind == KIND_PLANE) return dot3(q, x) < q[3] * std::sqrt(dot3(q, q));
  if (kind == KIND_SUPERELLIPSOID) return SuperEll(q).norm(x) < 1.0;
  if (kind == KIND_QUADRIC) return quadric_value(q, x) < 0.0;
  if (kind == KIND_POLY) {
    double c[POLY_TERMS];
    poly_coefficients(params, c);
    return poly_at(c, x) < 0.0;
  }
  if (kind == KIND_LATHE) {
    const PrismD<T> P = prism_of(params);
    return prism_filled(P, std::sqrt(x[0] * x[0] + x[2] * x[2]), x[1]);
  }
  if (kind == KIND_BLOB) return blob_field(params, x) > static_cast<double>(params[13]);
  if (kind == KIND_PRISM) {
    const PrismD<T> P = prism_of(params);
    if (P.open) return false;
    if (static_cast<int>(params[18]) == 2) std::swap(x[1], x[2]);
    if (!(x[1] > P.lo && x[1] < P.hi)) return false;
    const double scale = P.conic ? x[1] : 1.0;
    if (scale == 0.0) return false;
    return prism_filled(P, x[0] / scale, x[2] / scale);
  }
  return false;
}

template <typename T>
struct Scene {
  const T* node_box;
  const int32_t* node_info;
  const int32_t* order;
  const int32_t* kind;
  const int32_t* mask;
  const T* params;
  const int32_t* unit;  // (n_items,) the bounding unit of each item
  const T* unit_box;    // (n_units, 6) lo xyz, hi xyz
  const int32_t* program;  // the CSG units' programs (see CSG units)
  int64_t n_items, n_units, n_program;
};

inline bool slab(const double* box_lo, const double* box_hi, const double* o, const double* inv, double tmin,
                 double tmax) {
  for (int k = 0; k < 3; ++k) {
    double a = (box_lo[k] - o[k]) * inv[k], b = (box_hi[k] - o[k]) * inv[k];
    // min_num/max_num drop the NaN of 0·inf (origin on a slab, direction parallel): no restriction
    tmin = max_num(tmin, min_num(a, b));
    tmax = min_num(tmax, max_num(a, b));
  }
  return tmin <= tmax;
}

// ------------------------------------------------------------------------------------- CSG units
// A CSG object with a finite box (POV-Ray's bound: semantics §4.4) is one item of the hierarchy,
// of kind KIND_CSG; its members (its primitives, with the clipping objects) are items after the
// hierarchy's (never in `order`), and its program, in `program` from offset params[0], says which
// crossing of a member counts (the rule of _plan: a crossing of a member counts where the point is
// inside or outside other parts of the object, semantics §4.2):
//
//   [n_members, then per member: its item, its first condition, its number of conditions, its
//    bounds' node (0: none)]
//   a condition: [node, want] (the node's inside test must equal want)
//   a node: [op, inverse, a, b]: op 0 a member's inside test (a: its item), 1 all, 2 any,
//           3 difference (the first and none of the others) of the b nodes listed from offset a
//   the bounds' node: the same tree of the bounding objects' members, a leaf true where the ray
//           crosses that member beyond tmin; false: the member is not seen by the ray at all
//
// Every offset is absolute. The query visits a member's item with its first counted crossing, so
// the closest hit names the member, whose JAX kernel computes the hit again.
// A node's value, its leaves' (a member's item) given by leaf(item).
template <typename T, typename Leaf>
bool node_value(const Scene<T>& s, int32_t node, const Leaf& leaf) {
  const int32_t* n = s.program + node;
  bool v;
  if (n[0] == 0) {
    v = leaf(n[2]);
  } else {
    const int32_t* kids = s.program + n[2];
    if (n[0] == 1) {
      v = true;
      for (int32_t j = 0; j < n[3] && v; ++j) v = node_value(s, kids[j], leaf);
    } else if (n[0] == 2) {
      v = false;
      for (int32_t j = 0; j < n[3] && !v; ++j) v = node_value(s, kids[j], leaf);
    } else {
      v = n[3] > 0 && node_value(s, kids[0], leaf);
      for (int32_t j = 1; j < n[3] && v; ++j) v = !node_value(s, kids[j], leaf);
    }
  }
  return v != (n[1] != 0);
}

template <typename T>
bool node_inside(const Scene<T>& s, int32_t node, const double* p) {
  return node_value(s, node, [&](int32_t it) {
    return item_inside(s.kind[it], s.params + ITEM_PARAMS * static_cast<int64_t>(it), p);
  });
}

// Whether the ray crosses the node's leaves beyond tmin, as its tree combines them (a member's
// bounds: POV-Ray's bounded_by on an object without a box of its own, semantics §4.4).
template <typename T>
bool node_crossed(const Scene<T>& s, int32_t node, const double* o, const double* d, double tmin) {
  return node_value(s, node, [&](int32_t it) {
    return item_hit(s.kind[it], s.params + ITEM_PARAMS * static_cast<int64_t>(it), o, d, tmin, INFINITY) < INFINITY;
  });
}

// What a visitor of a CSG unit's counted crossings asks next (csg_crossings).
enum class Next { crossing, member, stop };

// The counted crossings in (tmin, limit) of the unit's members of mask `want`, member by member, each
// member's in order (each from the last): visit(member's item, t) says whether to go on with the
// member's next crossing, the next member, or stop (then returns true). `limit` may shrink as it
// goes (the first counted crossing narrows it).
template <typename T, typename Visit>
bool csg_crossings(const Scene<T>& s, int32_t item, const double* o, const double* d, double tmin, double& limit,
                   int32_t want, const Visit& visit) {
  const int32_t* prog = s.program + static_cast<int64_t>(s.params[ITEM_PARAMS * static_cast<int64_t>(item)]);
  for (int32_t m = 0; m < prog[0]; ++m) {
    const int32_t* mem = prog + 1 + MEMBER_INTS * m;
    const int32_t it = mem[0];
    if ((s.mask[it] & want) == 0) continue;
    if (mem[3] > 0 && !node_crossed(s, mem[3], o, d, tmin)) continue;  // its bounds missed
    const T* params = s.params + ITEM_PARAMS * static_cast<int64_t>(it);
    double t = tmin;
    // a polynomial's crossings, found once (each search finds them all)
    double roots[4];
    int n_roots = -1, next_root = 0;
    for (int k = 0; k < MAX_CROSSINGS; ++k) {
      if (s.kind[it] == KIND_POLY) {
        if (n_roots < 0) {
          double p[ITEM_PARAMS], c[POLY_TERMS];
          for (int j = 0; j < ITEM_PARAMS; ++j) p[j] = static_cast<double>(params[j]);
          poly_coefficients(params, c);
          n_roots = poly_crossings(c, to_object(p, o, d), roots);
        }
        while (next_root < n_roots && !(roots[next_root] > t)) ++next_root;
        t = next_root < n_roots && roots[next_root] < limit ? roots[next_root] : INFINITY;
      } else {
        t = item_hit(s.kind[it], params, o, d, t, limit);
      }
      if (!(t < limit)) break;
      const double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
      bool counts = true;
      for (int32_t c = 0; c < mem[2] && counts; ++c) {
        const int32_t* cond = s.program + mem[1] + 2 * c;
        counts = node_inside(s, cond[0], p) == (cond[1] != 0);
      }
      if (!counts) continue;
      const Next next = visit(it, t);
      if (next == Next::stop) return true;
      if (next == Next::member) break;
    }
  }
  return false;
}

// The first counted crossing in (tmin, tmax) of the unit's members of mask `want`; its member's item
// in `member` (-1 when none).
template <typename T>
double csg_hit(const Scene<T>& s, int32_t item, const double* o, const double* d, double tmin, double tmax,
               int32_t want, int32_t& member) {
  double best = tmax;
  member = -1;
  csg_crossings(s, item, o, d, tmin, best, want, [&](int32_t it, double t) {
    best = t;
    member = it;
    return Next::member;
  });
  return member >= 0 ? best : INFINITY;
}

// Visits, in near-to-far order of the hierarchy's nodes, every item of mask `want` that the segment
// (tmin, limit) of one ray crosses: visit(item, t) with its first crossing t, returning true to
// stop. `limit` may shrink as the walk goes (a closest-hit query narrows it to its best hit). A CSG
// object is visited as the member of its first counted crossing, or with EVERY = true as the member
// of each of its counted crossings.
template <typename T, typename Visit, bool EVERY = false>
void walk(const Scene<T>& s, const double* o, const double* d, double tmin, double& limit, int32_t want,
          const Visit& visit) {
  double inv[3];
  for (int k = 0; k < 3; ++k) inv[k] = 1.0 / d[k];
  int64_t stack[STACK];
  int sp = 0;
  stack[sp++] = 0;
  double lo[3], hi[3];
  while (sp > 0) {
    const int64_t node = stack[--sp];
    for (int k = 0; k < 3; ++k) {
      lo[k] = static_cast<double>(s.node_box[6 * node + k]);
      hi[k] = static_cast<double>(s.node_box[6 * node + 3 + k]);
    }
    if (!slab(lo, hi, o, inv, tmin, limit)) continue;
    const int32_t* info = s.node_info + 4 * node;
    if (info[1] > 0) {
      for (int32_t j = info[0]; j < info[0] + info[1]; ++j) {
        const int32_t it = s.order[j];
        if ((s.mask[it] & want) == 0) continue;
        if (EVERY && s.kind[it] == KIND_CSG) {  // each counted crossing (a filtered shadow's)
          double lim = limit;
          if (csg_crossings(s, it, o, d, tmin, lim, want,
                            [&](int32_t m, double t) { return visit(m, t) ? Next::stop : Next::crossing; }))
            return;
          continue;
        }
        if (s.kind[it] == KIND_CSG) {
          int32_t member;
          const double t = csg_hit(s, it, o, d, tmin, limit, want, member);
          if (member >= 0 && t < limit && visit(member, t)) return;
          continue;
        }
        double t = item_hit(s.kind[it], s.params + ITEM_PARAMS * static_cast<int64_t>(it), o, d, tmin, limit);
        if (t < limit && visit(it, t)) return;
      }
      continue;
    }
    const int64_t left = info[0], right = info[2];
    if (sp + 2 > STACK) continue;  // unreachable for the depths the build makes (see bvh_build)
    if (d[info[3]] < 0) {
      stack[sp++] = left;
      stack[sp++] = right;
    } else {
      stack[sp++] = right;
      stack[sp++] = left;
    }
  }
}

// Where the line o + t d enters the box (lo, hi): -inf for an unbounded box or an origin inside a
// slab the ray runs along, +inf when the line misses it.
inline double box_entry(const double* lo, const double* hi, const double* o, const double* d) {
  double t_near = -INFINITY, t_far = INFINITY;
  for (int k = 0; k < 3; ++k) {
    if (d[k] != 0.0) {
      double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
      t_near = max_num(t_near, min_num(a, b));
      t_far = min_num(t_far, max_num(a, b));
    } else if (o[k] < lo[k] || o[k] > hi[k]) {
      return INFINITY;
    }
  }
  return t_near <= t_far ? t_near : INFINITY;
}

template <typename T>
double unit_entry(const Scene<T>& s, int32_t unit, const double* o, const double* d) {
  if (unit < 0 || unit >= s.n_units) return INFINITY;  // (the tables are built with valid units)
  double lo[3], hi[3];
  for (int k = 0; k < 3; ++k) {
    lo[k] = static_cast<double>(s.unit_box[6 * unit + k]);
    hi[k] = static_cast<double>(s.unit_box[6 * unit + 3 + k]);
  }
  return box_entry(lo, hi, o, d);
}

// Closest (any_hit = false) or first found (any_hit = true) item of one ray; its distance in t_out
// (tmax when none). Closest: among items tied with the nearest (see Ties), the nearest item of the
// unit whose box the ray enters first, else of the earlier unit.
template <typename T>
int32_t traverse(const Scene<T>& s, const double* o, const double* d, double tmin, double tmax, int32_t want,
                 bool any_hit, double* t_out) {
  constexpr double TIE = 64.0 * std::numeric_limits<T>::epsilon();  // as _geometry.TIE_EPSILONS
  int32_t best = -1;
  double nearest = INFINITY, best_t = tmax, best_entry = NAN;
  double limit = tmax;
  walk(s, o, d, tmin, limit, want, [&](int32_t it, double t) {
    if (any_hit) {
      best = it;
      best_t = t;
      return true;
    }
    if (best < 0 || t < nearest - TIE * std::fabs(nearest)) {  // a new nearest: nothing ties with it yet
      best = it;
      best_t = nearest = t;
      best_entry = NAN;
    } else {  // tied with the nearest
      nearest = min_num(nearest, t);
      const int32_t u = s.unit[it], ub = s.unit[best];
      if (u == ub) {  // the same object: its nearer crossing
        if (t < best_t) {
          best = it;
          best_t = t;
        }
      } else {
        if (std::isnan(best_entry)) best_entry = unit_entry(s, ub, o, d);
        const double e = unit_entry(s, u, o, d);
        if (e < best_entry || (e == best_entry && u < ub)) {
          best = it;
          best_t = t;
          best_entry = e;
        }
      }
    }
    limit = min_num(tmax, nearest + TIE * std::fabs(nearest));  // narrows the walk's segment
    return false;
  });
  *t_out = best >= 0 ? best_t : tmax;
  return best;
}

// Every item with a crossing in (tmin, tmax) (a filtered shadow segment: each transparent item it
// crosses filters it), keeping the k nearest by their first crossing in out[0..k) (ascending, -1
// after the last) with that crossing in out_t; returns how many were crossed, which may exceed k.
// A CSG object gives one entry per counted crossing, naming its member. No node is
// pruned by a found hit: the whole segment is searched.
template <typename T>
int32_t traverse_all(const Scene<T>& s, const double* o, const double* d, double tmin, double tmax, int32_t want,
                     int32_t* out, double* out_t, int k) {
  int32_t found = 0;
  int kept = 0;
  auto visit = [&](int32_t it, double t) {
    ++found;
    if (kept == k && !(t < out_t[k - 1])) return false;
    int pos = kept < k ? kept++ : k - 1;  // insertion into the sorted list (drops the farthest)
    while (pos > 0 && out_t[pos - 1] > t) {
      out[pos] = out[pos - 1];
      out_t[pos] = out_t[pos - 1];
      --pos;
    }
    out[pos] = it;
    out_t[pos] = t;
    return false;
  };
  walk<T, decltype(visit), true>(s, o, d, tmin, tmax, want, visit);
  for (int j = kept; j < k; ++j) {
    out[j] = -1;
    out_t[j] = INFINITY;
  }
  return found;
}

template <ffi::DataType DT>
ffi::Error build_impl(ffi::Buffer<DT> boxes, ffi::ResultBuffer<DT> node_box, ffi::ResultBuffer<ffi::S32> node_info,
                      ffi::ResultBuffer<ffi::S32> order) {
  const int64_t n = static_cast<int64_t>(boxes.element_count()) / 6;
  if (n < 1) return ffi::Error(ffi::ErrorCode::kInvalidArgument, "bvh_build: no items");
  auto* nb = node_box->typed_data();
  auto* ni = node_info->typed_data();
  const int64_t m = static_cast<int64_t>(node_box->element_count()) / 6;
  if (m < 2 * n - 1 || static_cast<int64_t>(node_info->element_count()) != 4 * m ||
      static_cast<int64_t>(order->element_count()) != n)
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, "bvh_build: outputs too small");
  std::fill(nb, nb + 6 * m, 0);
  std::fill(ni, ni + 4 * m, 0);
  build(boxes.typed_data(), n, nb, ni, order->typed_data());
  return ffi::Error::Success();
}

// Runs body(begin, end) over chunks of [0, n) on XLA's intra-op thread pool and the calling thread.
// The caller takes chunks too and then waits only for chunks that a pool thread has already started
// (they are running, so they finish): it never waits on a task still queued behind other work, so
// two queries running at once on a busy pool cannot deadlock. A task that starts after every chunk
// is taken touches nothing but the shared counters it holds.
template <typename Body>
void parallel_for(ffi::ThreadPool& pool, int64_t n, const Body& body) {
  constexpr int64_t CHUNK = 256;
  const int64_t chunks = (n + CHUNK - 1) / CHUNK;
  const int64_t helpers = std::min<int64_t>(pool.num_threads(), chunks - 1);
  if (helpers <= 0) {
    body(0, n);
    return;
  }
  struct State {
    std::atomic<int64_t> next{0}, done{0};
    std::mutex mutex;
    std::condition_variable cv;
  };
  auto state = std::make_shared<State>();
  auto work = [state, chunks, n, &body] {
    int64_t c;
    while ((c = state->next.fetch_add(1)) < chunks) {
      body(c * CHUNK, std::min(n, (c + 1) * CHUNK));
      if (state->done.fetch_add(1) + 1 == chunks) {
        std::lock_guard<std::mutex> lock(state->mutex);
        state->cv.notify_all();
      }
    }
  };
  for (int64_t i = 0; i < helpers; ++i) {
    // a late task finds no chunk left and only reads the counters it keeps alive
    pool.Schedule([state, work] { work(); });
  }
  work();
  std::unique_lock<std::mutex> lock(state->mutex);
  state->cv.wait(lock, [&] { return state->done.load() == chunks; });
}

// The operands every query takes. rays_impl checks their sizes, then calls
// body(scene, ray index, origin, direction, tmin, tmax, want, valid) for every ray on XLA's thread
// pool, in double precision; `valid` is false for a non-finite ray or an empty segment.
template <ffi::DataType DT>
struct RayOperands {
  ffi::Buffer<DT> node_box;
  ffi::Buffer<ffi::S32> node_info, order, kind, mask;
  ffi::Buffer<DT> params;
  ffi::Buffer<ffi::S32> unit;
  ffi::Buffer<DT> unit_box;
  ffi::Buffer<ffi::S32> program;
  ffi::Buffer<DT> origin, direction, tmin, tmax;
  ffi::Buffer<ffi::S32> want;
};

// The handlers' parameters for RayOperands' fields, in the bindings' order, and their names.
#define RAY_OPERAND_PARAMS(DT)                                                                             \
  ffi::Buffer<DT> node_box, ffi::Buffer<ffi::S32> node_info, ffi::Buffer<ffi::S32> order,                \
      ffi::Buffer<ffi::S32> kind, ffi::Buffer<ffi::S32> mask, ffi::Buffer<DT> params,                    \
      ffi::Buffer<ffi::S32> unit, ffi::Buffer<DT> unit_box, ffi::Buffer<ffi::S32> program,              \
      ffi::Buffer<DT> origin, ffi::Buffer<DT> direction, ffi::Buffer<DT> tmin, ffi::Buffer<DT> tmax,     \
      ffi::Buffer<ffi::S32> want
#define RAY_OPERAND_NAMES \
  node_box, node_info, order, kind, mask, params, unit, unit_box, program, origin, direction, tmin, tmax, want

template <ffi::DataType DT, typename Body>
ffi::Error rays_impl(ffi::ThreadPool& pool, const RayOperands<DT>& a, const char* what, const Body& body) {
  using T = ffi::NativeType<DT>;
  Scene<T> s{a.node_box.typed_data(), a.node_info.typed_data(), a.order.typed_data(), a.kind.typed_data(),
             a.mask.typed_data(), a.params.typed_data(), a.unit.typed_data(), a.unit_box.typed_data(),
             a.program.typed_data(), static_cast<int64_t>(a.kind.element_count()),
             static_cast<int64_t>(a.unit_box.element_count()) / 6,
             static_cast<int64_t>(a.program.element_count())};
  const int64_t rays = static_cast<int64_t>(a.tmin.element_count());
  auto size = [](const auto& buffer) { return static_cast<int64_t>(buffer.element_count()); };
  if (size(a.origin) != 3 * rays || size(a.direction) != 3 * rays || size(a.tmax) != rays ||
      size(a.want) != rays || size(a.params) != ITEM_PARAMS * s.n_items || size(a.mask) != s.n_items ||
      size(a.order) > s.n_items || size(a.unit) != s.n_items || size(a.unit_box) != 6 * s.n_units)
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, std::string(what) + ": inconsistent operand sizes");
  const T* o = a.origin.typed_data();
  const T* d = a.direction.typed_data();
  const T* t0 = a.tmin.typed_data();
  const T* t1 = a.tmax.typed_data();
  const int32_t* w = a.want.typed_data();
  parallel_for(pool, rays, [&](int64_t begin, int64_t end) {
    for (int64_t r = begin; r < end; ++r) {
      double oo[3] = {double(o[3 * r]), double(o[3 * r + 1]), double(o[3 * r + 2])};
      double dd[3] = {double(d[3 * r]), double(d[3 * r + 1]), double(d[3 * r + 2])};
      const double lo = double(t0[r]), hi = double(t1[r]);
      const bool valid = std::isfinite(oo[0] + oo[1] + oo[2] + dd[0] + dd[1] + dd[2]) && lo < hi;
      body(s, r, oo, dd, lo, hi, w[r], valid);
    }
  });
  return ffi::Error::Success();
}

// operands -> item, t: the closest (any_hit = false) or a blocking (any_hit = true) item
template <ffi::DataType DT, bool any_hit>
ffi::Error query_impl(ffi::ThreadPool pool, RAY_OPERAND_PARAMS(DT),
                      ffi::ResultBuffer<ffi::S32> item, ffi::ResultBuffer<DT> t_out) {
  using T = ffi::NativeType<DT>;
  if (item->element_count() != tmin.element_count() || t_out->element_count() != tmin.element_count())
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, "bvh query: inconsistent result sizes");
  int32_t* out = item->typed_data();
  T* tout = t_out->typed_data();
  RayOperands<DT> a{RAY_OPERAND_NAMES};
  return rays_impl(pool, a, "bvh query",
                   [&](const Scene<T>& s, int64_t r, const double* o, const double* d, double lo, double hi,
                       int32_t w, bool valid) {
                     double t = INFINITY;
                     const int32_t hit = valid ? traverse(s, o, d, lo, hi, w, any_hit, &t) : -1;
                     out[r] = hit;
                     tout[r] = static_cast<T>(hit >= 0 ? t : INFINITY);
                   });
}

// operands -> item (rays, k), count, t (rays, k): the k nearest items a segment crosses, how many it
// crosses, and each one's crossing (its first; a CSG member's counted one)
template <ffi::DataType DT>
ffi::Error all_impl(ffi::ThreadPool pool, RAY_OPERAND_PARAMS(DT),
                    ffi::ResultBuffer<ffi::S32> item,
                    ffi::ResultBuffer<ffi::S32> count,
                    ffi::ResultBuffer<DT> t_out) {
  using T = ffi::NativeType<DT>;
  const int64_t rays = static_cast<int64_t>(tmin.element_count());
  if (rays == 0) return ffi::Error::Success();
  const int64_t k = static_cast<int64_t>(item->element_count()) / rays;
  if (k < 1 || k > 1024 || static_cast<int64_t>(item->element_count()) != k * rays ||
      static_cast<int64_t>(count->element_count()) != rays ||
      static_cast<int64_t>(t_out->element_count()) != k * rays)
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, "bvh all-crossings query: inconsistent result sizes");
  int32_t* out = item->typed_data();
  int32_t* cnt = count->typed_data();
  T* tt = t_out->typed_data();
  RayOperands<DT> a{RAY_OPERAND_NAMES};
  return rays_impl(pool, a, "bvh all-crossings query",
                   [&](const Scene<T>& s, int64_t r, const double* o, const double* d, double lo, double hi,
                       int32_t w, bool valid) {
                     int32_t* row = out + k * r;
                     T* trow = tt + k * r;
                     if (!valid) {
                       cnt[r] = 0;
                       std::fill(row, row + k, -1);
                       std::fill(trow, trow + k, static_cast<T>(INFINITY));
                       return;
                     }
                     thread_local std::vector<double> ts;
                     ts.resize(k);
                     cnt[r] = traverse_all(s, o, d, lo, hi, w, row, ts.data(), static_cast<int>(k));
                     for (int64_t j = 0; j < k; ++j) trow[j] = static_cast<T>(ts[j]);
                   });
}

}  // namespace

// node_box, node_info, order, kind, mask, params, unit, unit_box, program, origin, direction, tmin, tmax,
// want -> item, SECOND
#define QUERY_BINDING(DT, SECOND)                                                                          \
  ffi::Ffi::Bind()                                                                                       \
      .Ctx<ffi::ThreadPool>()                                                                            \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<DT>>()                                                                            \
      .Arg<ffi::Buffer<ffi::S32>>()                                                                      \
      .Ret<ffi::Buffer<ffi::S32>>()                                                                      \
      .Ret<ffi::Buffer<SECOND>>()

XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhBuildF32, build_impl<ffi::F32>,
                              ffi::Ffi::Bind()
                                  .Arg<ffi::Buffer<ffi::F32>>()
                                  .Ret<ffi::Buffer<ffi::F32>>()
                                  .Ret<ffi::Buffer<ffi::S32>>()
                                  .Ret<ffi::Buffer<ffi::S32>>());
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhBuildF64, build_impl<ffi::F64>,
                              ffi::Ffi::Bind()
                                  .Arg<ffi::Buffer<ffi::F64>>()
                                  .Ret<ffi::Buffer<ffi::F64>>()
                                  .Ret<ffi::Buffer<ffi::S32>>()
                                  .Ret<ffi::Buffer<ffi::S32>>());
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhClosestF32, (query_impl<ffi::F32, false>), QUERY_BINDING(ffi::F32, ffi::F32));
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhClosestF64, (query_impl<ffi::F64, false>), QUERY_BINDING(ffi::F64, ffi::F64));
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhAnyF32, (query_impl<ffi::F32, true>), QUERY_BINDING(ffi::F32, ffi::F32));
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhAnyF64, (query_impl<ffi::F64, true>), QUERY_BINDING(ffi::F64, ffi::F64));
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhAllF32, all_impl<ffi::F32>,
                              QUERY_BINDING(ffi::F32, ffi::S32).Ret<ffi::Buffer<ffi::F32>>());
XLA_FFI_DEFINE_HANDLER_SYMBOL(BvhAllF64, all_impl<ffi::F64>,
                              QUERY_BINDING(ffi::F64, ffi::S32).Ret<ffi::Buffer<ffi::F64>>());
