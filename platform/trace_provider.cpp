// The single translation unit that instantiates the `haptic` tracepoint probes and their
// registration (lttng-ust 2.13). Compiled to nothing when HAPTIC_WITH_LTTNG is 0.
#if HAPTIC_WITH_LTTNG
#define LTTNG_UST_TRACEPOINT_CREATE_PROBES
#define LTTNG_UST_TRACEPOINT_DEFINE
#include "platform/trace_provider.h"
#endif
namespace haptic::platform::trace {
// Lets tools and tests report whether tracepoints were compiled in.
extern const bool kCompiledIn = HAPTIC_WITH_LTTNG != 0;
}  // namespace haptic::platform::trace
