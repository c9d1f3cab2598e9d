// Text output helpers: exact number formatting and atomic file replacement.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

namespace qd::runtime {

// Shortest text that reads back to the same double ("nan" and "inf" spelled as pandas reads them).
void append_number(std::string& out, double v);
std::string format_number(double v);
void append_int(std::string& out, std::int64_t v);

// Writes `content` to `path` atomically: a temporary file in the same directory, fsync, rename.
// Readers see either the old file or the new one, never a torn write.
void write_file_atomic(const std::filesystem::path& path, const std::string& content);

// Makes a finished temporary file durable and moves it over `path` (fsync, rename, fsync dir).
void commit_file(const std::filesystem::path& tmp, const std::filesystem::path& path);

// Appends text and flushes it to the OS (so a killed run keeps every completed row).
void append_to_file(const std::filesystem::path& path, const std::string& text);

}  // namespace qd::runtime
