// The rows of the model files mmetric writes (--outputModelA/B, mm sample -o) as text, byte for byte: float32 values
// as C's "%.9g" of the value promoted to double (mmetric streams them at precision 9, which glibc prints with %.9g),
// integers in decimal, each value followed by its column's separator.
//
// std::to_chars(double, chars_format::general, 9) is specified as printf's "%.9g" in the "C" locale, and libstdc++
// computes it exactly (Ryu printf) about 3x faster than glibc's snprintf: the same bytes for every float32, -0, inf,
// subnormals and values next to powers of ten included, and "-nan" for a NaN whose sign bit is set, as glibc prints it
// (tests/mpeg/test_model_text.py checks millions of bit patterns against Python's format and glibc's snprintf). The
// rows are formatted in blocks on torch's threads, each block into its own stretch of one buffer, then packed.
// Compiled into the "pcc" extension (mpeg_pcc.cpp binds it); torchmeshmetric.mpeg.core.text_rows calls it.
#include <torch/extension.h>

#include <charconv>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "parallel.h"

namespace {

constexpr int64_t FLOAT_CHARS = 24;  // "%.9g" of a float needs at most 15 ("-1.17549435e-38")
constexpr int64_t INT_CHARS = 20;    // "-9223372036854775808"
constexpr int64_t BLOCK_ROWS = 4096;

}  // namespace

// The rows' text: prefix, then each value followed by its separator (floats (n, cf) first, then ints (n, ci)).
pybind11::bytes format_model_rows(const torch::Tensor& floats, const torch::Tensor& ints, const std::string& prefix,
                                  const std::vector<std::string>& seps) {
  TORCH_CHECK(floats.dim() == 2 && floats.scalar_type() == torch::kFloat32 && floats.is_contiguous() &&
                  floats.device().is_cpu(),
              "format_model_rows: floats must be a contiguous (n, cf) float32 CPU tensor");
  TORCH_CHECK(ints.dim() == 2 && ints.scalar_type() == torch::kInt64 && ints.is_contiguous() && ints.device().is_cpu(),
              "format_model_rows: ints must be a contiguous (n, ci) int64 CPU tensor");
  const int64_t n = floats.size(0), cf = floats.size(1), ci = ints.size(1);
  TORCH_CHECK(ints.size(0) == n, "format_model_rows: floats and ints must have as many rows, found ", n, " and ",
              ints.size(0));
  TORCH_CHECK(static_cast<int64_t>(seps.size()) == cf + ci, "format_model_rows: one separator per column expected (",
              cf + ci, "), found ", seps.size());
  int64_t row_max = static_cast<int64_t>(prefix.size()) + cf * FLOAT_CHARS + ci * INT_CHARS;
  for (const auto& s : seps) row_max += static_cast<int64_t>(s.size());
  const float* f = floats.data_ptr<float>();
  const int64_t* k = ints.data_ptr<int64_t>();
  const int64_t blocks = (n + BLOCK_ROWS - 1) / BLOCK_ROWS;
  std::vector<char> buf(static_cast<size_t>(n * row_max));
  std::vector<int64_t> used(static_cast<size_t>(blocks), 0);
  {
    pybind11::gil_scoped_release release;
    tmm::chunked_for(blocks, 1, [&](int64_t b0, int64_t b1) {
      for (int64_t b = b0; b < b1; ++b) {
        char* const start = buf.data() + b * BLOCK_ROWS * row_max;
        char* p = start;
        for (int64_t r = b * BLOCK_ROWS, end = std::min(n, (b + 1) * BLOCK_ROWS); r < end; ++r) {
          char* const row_end = p + row_max;  // the bound of this row: to_chars never writes past it
          std::memcpy(p, prefix.data(), prefix.size());
          p += prefix.size();
          for (int64_t j = 0; j < cf + ci; ++j) {
            // float promoted to double, as printf's variadic call promotes it
            const auto res = j < cf ? std::to_chars(p, row_end, static_cast<double>(f[r * cf + j]),
                                                    std::chars_format::general, 9)
                                    : std::to_chars(p, row_end, k[r * ci + (j - cf)]);
            TORCH_CHECK(res.ec == std::errc(), "format_model_rows: row bound exceeded");  // cannot happen
            p = res.ptr;
            std::memcpy(p, seps[j].data(), seps[j].size());
            p += seps[j].size();
          }
        }
        used[b] = p - start;
      }
    });
    int64_t packed = 0;  // the blocks' text moved together (each starts at or after the end of the previous one)
    for (int64_t b = 0; b < blocks; ++b) {
      std::memmove(buf.data() + packed, buf.data() + b * BLOCK_ROWS * row_max, static_cast<size_t>(used[b]));
      packed += used[b];
    }
    buf.resize(static_cast<size_t>(packed));
  }
  return pybind11::bytes(buf.data(), buf.size());
}
