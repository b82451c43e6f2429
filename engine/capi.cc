// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// The C entry points of the library for the Python layer (ctypes): the layout of the tables,
// the instance of a model, passes in the explicit and query modes, and views of the state.

#include <cstring>
#include <string>

#include "api.h"
#include "forward.h"
#include "granular.h"
#include "watch.h"

namespace {

std::string Layout() {
  std::string out = "format " + std::to_string(mjrft::kTableFormat) + "\nsizes";
#define MJRFT_X(name) out += " " #name;
  MJRFT_TABLE_SIZES(MJRFT_X)
#undef MJRFT_X
  out += "\nscalars";
#define MJRFT_X(type, name, doc) out += " " #type ":" #name;
  MJRFT_TABLE_SCALARS(MJRFT_X)
#undef MJRFT_X
  out += "\narrays";
#define MJRFT_X(type, name, size, doc) out += " " #type ":" #name;
  MJRFT_TABLE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  out += "\nstate";
#define MJRFT_X(type, name, size, doc) out += " " #type ":" #name;
  MJRFT_STATE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  return out + "\n";
}

}  // namespace

// The tables' and the state's layout, one line each: "format N", "sizes name ...",
// "scalars type:name ...", "arrays type:name ...", "state type:name ..." (fields.h).
MJRFT_API const char* mjrft_layout() {
  static const std::string layout = Layout();
  return layout.c_str();
}

// The index of m's mjrft.granular instance, or -1.
MJRFT_API int mjrft_instance(const mjModel* m) { return mjrft::GranularInstance(m); }

// A pass of the engine on d in the given mode (forward.h); returns its status, or 1 if d has no
// usable instance.
MJRFT_API long long mjrft_forward(const mjModel* m, mjData* d, int instance, int mode) {
  std::string error;
  mjrft::Instance* in = mjrft::Instance::Of(m, d, instance, &error);
  if (!in) return 1;
  return in->Run(m, d, mode);
}

// The address of state array `name` of d's instance (element type and size: fields.h), or null.
MJRFT_API void* mjrft_state_array(const mjModel* m, mjData* d, int instance, const char* name) {
  std::string error;
  mjrft::Instance* in = mjrft::Instance::Of(m, d, instance, &error);
  if (!in) return nullptr;
  mjrft::State s = in->Bind(m, d);
#define MJRFT_X(type, field, size, doc) \
  if (std::strcmp(name, #field) == 0) return static_cast<void*>(s.field);
  MJRFT_STATE_ARRAYS(MJRFT_X)
#undef MJRFT_X
  return nullptr;
}

// The number of elements of state array `name` of d's instance (fields.h), or -1.
MJRFT_API long long mjrft_state_size(const mjModel* m, mjData* d, int instance, const char* name) {
  std::string error;
  mjrft::Instance* in = mjrft::Instance::Of(m, d, instance, &error);
  return in ? in->ArraySize(name) : -1;
}

// The MuJoCo version the library was compiled against (mjVERSION_HEADER).
MJRFT_API int mjrft_mujoco_version() { return mjVERSION_HEADER; }

// Sets the receiver of the engine's reports of geoms that sink without being intruders
// (watch.h); null: MuJoCo's mju_warning.
MJRFT_API void mjrft_set_report_handler(void (*handler)(const char* message)) {
  mjrft::watch::SetHandler(handler);
}
