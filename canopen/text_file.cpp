#include "canopen/text_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace oegw::canopen {

namespace {

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

// Closes the descriptor on every path out of read_text_file.
struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

TextFile read_text_file(const std::string& path, std::size_t max_bytes) {
  TextFile out;
  const Fd f{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY)};
  if (f.fd < 0) {
    out.error = std::string("cannot open: ") + std::strerror(errno) + "; expected a readable file";
    return out;
  }
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) {
    out.error = std::string("cannot read: ") + std::strerror(errno) + "; expected a readable file";
    return out;
  }
  if (!S_ISREG(st.st_mode)) {
    out.error = "is " + kind_of(st.st_mode) + "; expected a regular file";
    return out;
  }
  const auto too_big = [&] {
    out.error = "is larger than " + std::to_string(max_bytes) + " bytes; expected a file of at most " +
                std::to_string(max_bytes) + " bytes";
  };
  if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    too_big();
    return out;
  }
  std::string text;
  text.reserve(static_cast<std::size_t>(st.st_size));
  char buf[8192];
  for (;;) {
    const ssize_t n = ::read(f.fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      out.error = std::string("cannot read: ") + std::strerror(errno) + "; expected a readable file";
      return out;
    }
    if (n == 0) break;
    if (text.size() + static_cast<std::size_t>(n) > max_bytes) {  // the file grew while read
      too_big();
      return out;
    }
    text.append(buf, static_cast<std::size_t>(n));
  }
  out.text = std::move(text);
  return out;
}

}  // namespace oegw::canopen
