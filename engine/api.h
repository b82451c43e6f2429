// Copyright 2026 The mjrft authors. Licensed under the Apache License, Version 2.0.
//
// Symbols the library exports to C callers (the Python layer calls them through ctypes).

#ifndef MJRFT_ENGINE_API_H_
#define MJRFT_ENGINE_API_H_

#if defined(_WIN32)
#define MJRFT_API extern "C" __declspec(dllexport)
#else
#define MJRFT_API extern "C" __attribute__((visibility("default")))
#endif

#endif  // MJRFT_ENGINE_API_H_
