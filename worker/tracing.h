// The tracing library's public face (CMake target tcfarm_tracing): what a program that
// renders frames needs, and all it should include. Its users are the worker daemon
// (worker/daemon), the standalone renderer (worker/render) and the coordinator's referee
// (coordinator/farm/referee.cpp, the one crossing between the two components: it traces
// disputed and stranded pixels itself, with the very code the workers run, so its answers
// are the workers' bits). Everything else under worker/ is the library's inside.
#pragma once

#include "worker/embree/device.h"          // EmbreeDevice: one per process
#include "worker/trace/tracer.h"           // Tracer: a scene's frames, pixels and horizons
#include "worker/util/tracing_threads.h"   // TracingThreads: the cores a tracer may use
