// POV-Ray's adaptive anti-aliasing rule (method 1) as the plain loop it is, called from JAX through
// XLA's FFI (_adaptive._scan_flags; semantics §3.3).
//
// In scan order (rows top to bottom, each left to right) a pixel's centre is compared with its left
// and upper neighbours' values as they are then: the neighbour's refined value once that neighbour
// is flagged, its centre before. A difference of at least `threshold` (the sum over R, G and B of
// the absolute differences) flags both. The colours come in already raised to 1/Antialias_Gamma and
// without a gradient: this only chooses which pixels are refined.
//
// _adaptive._scan_flags computes the same flags with cumulative operations (rows repeated to a fixed
// point), for devices other than the CPU and where this library is not built; on the CPU that
// program costs ~0.4 ms a call at 128×96, this loop a few microseconds.

#include <cmath>
#include <cstdint>

#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

namespace {

// centre, refined: (H, W, 3); threshold: one value; flag: (H, W)
template <ffi::DataType DT>
ffi::Error flags_impl(ffi::Buffer<DT> centre, ffi::Buffer<DT> refined, ffi::Buffer<DT> threshold,
                      ffi::ResultBuffer<ffi::PRED> flag) {
  using T = ffi::NativeType<DT>;
  const auto dims = centre.dimensions();
  if (dims.size() != 3 || dims[2] != 3)
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, "anti-aliasing rule: the centres must be (H, W, 3)");
  const int64_t h = dims[0], w = dims[1];
  if (refined.element_count() != centre.element_count() || threshold.element_count() != 1 ||
      static_cast<int64_t>(flag->element_count()) != h * w)
    return ffi::Error(ffi::ErrorCode::kInvalidArgument, "anti-aliasing rule: inconsistent sizes");
  const T* c = centre.typed_data();
  const T* a = refined.typed_data();
  const T limit = threshold.typed_data()[0];
  bool* f = flag->typed_data();
  for (int64_t p = 0; p < h * w; ++p) f[p] = false;
  // the same sum, in the same order and type, as the JAX rule: (|dr| + |dg|) + |db| >= threshold
  auto differs = [&](int64_t p, int64_t q) {
    const T* x = c + 3 * p;
    const T* y = (f[q] ? a : c) + 3 * q;
    const T sum = (std::abs(x[0] - y[0]) + std::abs(x[1] - y[1])) + std::abs(x[2] - y[2]);
    return sum >= limit;
  };
  for (int64_t y = 0; y < h; ++y) {
    for (int64_t x = 0; x < w; ++x) {
      const int64_t p = y * w + x;
      // neither comparison changes what the other reads: flagging p changes no value read at p,
      // and no later pixel reads the upper neighbour of p
      if (x > 0 && differs(p, p - 1)) f[p] = f[p - 1] = true;
      if (y > 0 && differs(p, p - w)) f[p] = f[p - w] = true;
    }
  }
  return ffi::Error::Success();
}

}  // namespace

#define FLAGS_BINDING(DT)                                                                        \
  ffi::Ffi::Bind()                                                                               \
      .Arg<ffi::Buffer<DT>>()                                                                    \
      .Arg<ffi::Buffer<DT>>()                                                                    \
      .Arg<ffi::Buffer<DT>>()                                                                    \
      .Ret<ffi::Buffer<ffi::PRED>>()

XLA_FFI_DEFINE_HANDLER_SYMBOL(AaFlagsF32, flags_impl<ffi::F32>, FLAGS_BINDING(ffi::F32));
XLA_FFI_DEFINE_HANDLER_SYMBOL(AaFlagsF64, flags_impl<ffi::F64>, FLAGS_BINDING(ffi::F64));
