/* LTTng-UST tracepoint provider `haptic` (lttng-ust 2.13 API, as shipped by Debian 12).
 * Included only through platform/trace.hpp (and once with CREATE_PROBES by trace_provider.cpp).
 * Field names are part of the trace format read by tools/trace/analyze.py: keep them stable. */
#undef LTTNG_UST_TRACEPOINT_PROVIDER
#define LTTNG_UST_TRACEPOINT_PROVIDER haptic

#undef LTTNG_UST_TRACEPOINT_INCLUDE
#define LTTNG_UST_TRACEPOINT_INCLUDE "platform/trace_provider.h"

#if !defined(HAPTIC_PLATFORM_TRACE_PROVIDER_H) || defined(LTTNG_UST_TRACEPOINT_HEADER_MULTI_READ)
#define HAPTIC_PLATFORM_TRACE_PROVIDER_H

#include <lttng/tracepoint.h>
#include <stdint.h>

/* A tick woke up: its index, its absolute CLOCK_MONOTONIC deadline and how late it woke. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, tick_begin,
  LTTNG_UST_TP_ARGS(uint64_t, tick, int64_t, scheduled_ns, int64_t, wake_latency_ns),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint64_t, tick, tick)
    lttng_ust_field_integer(int64_t, scheduled_ns, scheduled_ns)
    lttng_ust_field_integer(int64_t, wake_latency_ns, wake_latency_ns)))

/* The tick's callback returned: its execution time measured by the loop. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, tick_end,
  LTTNG_UST_TP_ARGS(uint64_t, tick, int64_t, exec_ns),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint64_t, tick, tick)
    lttng_ust_field_integer(int64_t, exec_ns, exec_ns)))

/* A stage of the tick (ids: haptic::platform::trace::Stage) began / ended. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, stage_begin,
  LTTNG_UST_TP_ARGS(uint8_t, stage),
  LTTNG_UST_TP_FIELDS(lttng_ust_field_integer(uint8_t, stage, stage)))
LTTNG_UST_TRACEPOINT_EVENT(haptic, stage_end,
  LTTNG_UST_TP_ARGS(uint8_t, stage),
  LTTNG_UST_TP_FIELDS(lttng_ust_field_integer(uint8_t, stage, stage)))

/* A state packet was received from / sent to a peer station. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, packet_rx,
  LTTNG_UST_TP_ARGS(uint32_t, peer, uint64_t, seq, uint32_t, bytes),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint32_t, peer, peer)
    lttng_ust_field_integer(uint64_t, seq, seq)
    lttng_ust_field_integer(uint32_t, bytes, bytes)))
LTTNG_UST_TRACEPOINT_EVENT(haptic, packet_tx,
  LTTNG_UST_TP_ARGS(uint32_t, peer, uint64_t, seq, uint32_t, bytes),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint32_t, peer, peer)
    lttng_ust_field_integer(uint64_t, seq, seq)
    lttng_ust_field_integer(uint32_t, bytes, bytes)))

/* Device sample read by the tick / force command written for the device. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, device_read,
  LTTNG_UST_TP_ARGS(uint32_t, device, uint64_t, sample_seq),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint32_t, device, device)
    lttng_ust_field_integer(uint64_t, sample_seq, sample_seq)))
LTTNG_UST_TRACEPOINT_EVENT(haptic, device_write,
  LTTNG_UST_TP_ARGS(uint32_t, device, uint64_t, command_seq),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint32_t, device, device)
    lttng_ust_field_integer(uint64_t, command_seq, command_seq)))

/* A tick ended after the next deadline: how many periods were skipped and how late it was. */
LTTNG_UST_TRACEPOINT_EVENT(haptic, overrun,
  LTTNG_UST_TP_ARGS(uint64_t, tick, uint64_t, missed_cycles, int64_t, late_ns),
  LTTNG_UST_TP_FIELDS(
    lttng_ust_field_integer(uint64_t, tick, tick)
    lttng_ust_field_integer(uint64_t, missed_cycles, missed_cycles)
    lttng_ust_field_integer(int64_t, late_ns, late_ns)))

#endif /* HAPTIC_PLATFORM_TRACE_PROVIDER_H */

#include <lttng/tracepoint-event.h>
