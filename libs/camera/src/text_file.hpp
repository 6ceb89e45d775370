#pragma once
// Internal helpers shared by the loaders: bounded whole-file reads and number parsing.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace evpipe::camera::detail {

/// Reads a whole (small) text file. Checks the size against max_bytes BEFORE allocating.
/// @throws ModelError(path, "", ...) if it cannot be opened/read or is too large.
std::string read_text_file(const std::string& path, std::uintmax_t max_bytes);
/// Refuses what is not a regular file (a FIFO without a writer would block std::ifstream for ever).
/// @throws ModelError(path, "", ...).
void check_input(const std::string& path);

/// Strips a UTF-8 byte order mark.
std::string_view strip_bom(std::string_view text);
/// Trims spaces, tabs, CR and LF at both ends.
std::string_view trim(std::string_view s);

/// Whole-string parse (after trim) of a finite double / an int64; nullopt on any trailing garbage,
/// overflow or non-finite value.
std::optional<double> parse_double(std::string_view s);
std::optional<std::int64_t> parse_int64(std::string_view s);

/// The file name without directories and extension ("config/roadheader.dxf" → "roadheader").
std::string stem_of(const std::string& path);

/// Short printable excerpt of a cell for messages (at most 40 characters, quoted by the caller).
std::string excerpt(std::string_view s);

}  // namespace evpipe::camera::detail
