// Shorthands for the coordinator's and the workers' Prometheus metrics: each registers a
// family and returns its one unlabelled child, kept by reference so hot paths only
// increment.
#pragma once

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/registry.h>

namespace tcfarm {

inline prometheus::Counter& NewCounter(prometheus::Registry& registry, const char* name,
                                       const char* help) {
  return prometheus::BuildCounter().Name(name).Help(help).Register(registry).Add({});
}

inline prometheus::Gauge& NewGauge(prometheus::Registry& registry, const char* name,
                                   const char* help) {
  return prometheus::BuildGauge().Name(name).Help(help).Register(registry).Add({});
}

// A counter family whose children are told apart by `type` (rays by ray type, say).
inline prometheus::Family<prometheus::Counter>& NewCounterFamily(prometheus::Registry& registry,
                                                                 const char* name,
                                                                 const char* help) {
  return prometheus::BuildCounter().Name(name).Help(help).Register(registry);
}

}  // namespace tcfarm
