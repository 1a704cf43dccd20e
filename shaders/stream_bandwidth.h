#pragma once
/// \file stream_bandwidth.h
/// The memory bandwidth that a streaming compute shader reaches on the current OpenGL device:
/// the bound against which `fascicle bench gpu` compares the `gl` Verlet kernels (the GPU
/// counterpart of the CPU spring bench's stream figure). A copy kernel (stream_copy.comp) moves
/// one buffer into another; bandwidth = bytes read + bytes written per second, best of the timed
/// repetitions.

#include "shaders/gl_context.h"

#include <cstddef>

namespace fascicle::shaders {

/// Options of measure_stream_bandwidth.
struct StreamBandwidthOptions {
  std::size_t bytes = std::size_t(256) << 20;  ///< size of each of the two buffers, a multiple of 16,
                                               ///< at most 64 GiB (default 256 MiB)
  int repetitions = 5;                         ///< timed repetitions, the best is kept (default 5)
  double min_seconds = 0.05;  ///< each repetition doubles its dispatches until it takes this long (default 0.05 s)
  /// Throws OptionError naming the bad field.
  void validate() const;
};

/// What measure_stream_bandwidth saw.
struct StreamBandwidth {
  double gb_per_second = 0.0;  ///< (bytes read + bytes written) / seconds / 1e9, best repetition
  std::size_t bytes = 0;       ///< bytes of each buffer
  int dispatches = 0;          ///< copies in the best repetition
  double seconds = 0.0;        ///< time of the best repetition
};

/// Measures the stream bandwidth on `context` (made current). The copy is checked: the
/// destination's first and last 4096 vec4s read back must equal the source's, else GpuError. Throws GpuError on GL errors (a
/// buffer the device cannot allocate), OptionError for bad options.
StreamBandwidth measure_stream_bandwidth(const GlContext& context, const StreamBandwidthOptions& options = {});

}  // namespace fascicle::shaders
