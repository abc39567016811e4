// The component classes built into this repository.
//
// Real-time contract: not RT-safe (set-up only).
#pragma once

#include "rack/core/registry.h"

namespace rack::components {

// Registers every built-in class (Generator, Monitor, Probe, ...), and the TiMS class
// name of every class of the tree, plug-ins included (rack::class_ids::kTreeClasses).
void register_builtin(ComponentRegistry& registry);

}  // namespace rack::components
