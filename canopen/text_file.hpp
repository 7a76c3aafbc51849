// Reading a configuration file (a mapping file, an EDS) whole, with the limits every reader of
// such a file needs: only a regular file is read (a FIFO would block forever, /dev/zero would
// fill memory, a directory reads as nothing), and only up to a size limit, checked before and
// while reading. What the file's bytes mean is the caller's business.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace oegw::canopen {

struct TextFile {
  std::optional<std::string> text;  // the whole file, or nullopt with `error`
  std::string error;                // "is a directory; expected a regular file", without the path
};

// Reads `path` if it is a regular file of at most `max_bytes` bytes. Opens without blocking
// (O_NONBLOCK: a FIFO named here is refused, not waited on) and checks the opened file's type, so
// a file swapped between a check and the open is still refused.
[[nodiscard]] TextFile read_text_file(const std::string& path, std::size_t max_bytes);

}  // namespace oegw::canopen
