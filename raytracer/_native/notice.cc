// A warning the compiled program raises while it runs (raytracer/_notice.py): rays that did not fit
// the ray tree's room, crossings the boundary term had no room for.
//
// Counts known only when a jitted program runs reach Python through this custom call instead of a
// JAX host callback: a program holding a host callback is neither kept by JAX's persistent
// compilation cache nor serialisable, where this target is a name that any process which loaded the
// library resolves. The call returns at once when every count is zero; otherwise it hands the
// counts and the call's static values to the sink that Python installed (the warning is raised
// there). A sink that reports an error (a warning filter turned the warning into one) fails the
// program with its message, as a failing host callback would.

#include <atomic>
#include <cstdint>
#include <vector>

#include "xla/ffi/api/ffi.h"

namespace ffi = xla::ffi;

// The call has one unused scalar result: XLA's partitioner drops the sharding of a call without
// results, and wants one on every side-effecting instruction.
//
// code: which warning; values: the counts, then the static values; returns null, or the message of
// the error the warning became (owned by the sink, valid until its next call)
using NoticeSink = const char* (*)(int64_t code, int64_t n, const int64_t* values);

namespace {

std::atomic<NoticeSink> sink{nullptr};

ffi::Error notice_impl(ffi::Buffer<ffi::S32> counts, int64_t code, ffi::Span<const int64_t> info,
                       ffi::ResultBuffer<ffi::S32> unused) {
  unused->typed_data()[0] = 0;
  const int64_t n = static_cast<int64_t>(counts.element_count());
  const int32_t* c = counts.typed_data();
  bool any = false;
  for (int64_t i = 0; i < n; ++i) any = any || c[i] > 0;
  NoticeSink s = sink.load();
  if (!any || s == nullptr) return ffi::Error::Success();
  std::vector<int64_t> values(c, c + n);
  values.insert(values.end(), info.begin(), info.end());
  const char* failed = s(code, static_cast<int64_t>(values.size()), values.data());
  if (failed != nullptr) return ffi::Error(ffi::ErrorCode::kAborted, failed);
  return ffi::Error::Success();
}

}  // namespace

extern "C" void SetNoticeSink(NoticeSink s) { sink.store(s); }

XLA_FFI_DEFINE_HANDLER_SYMBOL(Notice, notice_impl,
                              ffi::Ffi::Bind()
                                  .Arg<ffi::Buffer<ffi::S32>>()
                                  .Attr<int64_t>("code")
                                  .Attr<ffi::Span<const int64_t>>("info")
                                  .Ret<ffi::Buffer<ffi::S32>>());
