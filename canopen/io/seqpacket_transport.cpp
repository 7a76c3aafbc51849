#include "canopen/io/seqpacket_transport.hpp"

#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <stdexcept>
#include <system_error>

namespace oegw::canopen::io {

void SeqpacketCanTransport::make_socketpair(int (&fds)[2]) {
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, fds) != 0)
    throw std::system_error(errno, std::generic_category(), "socketpair(AF_UNIX, SOCK_SEQPACKET)");
}

std::unique_ptr<SeqpacketCanTransport> SeqpacketCanTransport::adopt(int fd, std::size_t max_batch) {
  if (fd < 0) throw std::invalid_argument("SeqpacketCanTransport::adopt: invalid file descriptor");
  prepare_adopted(fd);
  return std::unique_ptr<SeqpacketCanTransport>(new SeqpacketCanTransport(fd, max_batch));
}

SeqpacketCanTransport::Pair SeqpacketCanTransport::pair(std::size_t max_batch) {
  int fds[2];
  make_socketpair(fds);
  Pair p;
  p.a = adopt(fds[0], max_batch);
  p.b = adopt(fds[1], max_batch);
  return p;
}

}  // namespace oegw::canopen::io
