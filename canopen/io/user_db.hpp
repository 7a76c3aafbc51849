// Reentrant lookups in the user and group databases (getpwuid_r, getgrnam_r, getgrgid_r): a
// SIGHUP reload checks its file in a thread beside the event loop (gateway/programs.cpp), which
// looks users and groups up too (the control socket), and the plain calls' results live in
// buffers of the process.
#pragma once

#include <cerrno>
#include <cstddef>
#include <optional>
#include <vector>

namespace oegw::canopen::io {

// `lookup(entry, buf, size, found)` is one of the *_r calls with its key bound, returning its
// error number; the entry's strings point into `buf`, which must outlive them. The buffer grows
// while the call says ERANGE, up to 1 MiB. nullopt: no such entry, or the lookup failed.
template <class Entry, class Lookup>
std::optional<Entry> look_up(Lookup lookup, std::vector<char>& buf) {
  buf.resize(1024);
  for (;;) {
    Entry e{};
    Entry* found = nullptr;
    const int error = lookup(&e, buf.data(), buf.size(), &found);
    if (error == ERANGE && buf.size() < (std::size_t{1} << 20)) {
      buf.resize(buf.size() * 2);
      continue;
    }
    if (error != 0 || found == nullptr) return std::nullopt;
    return e;
  }
}

}  // namespace oegw::canopen::io
