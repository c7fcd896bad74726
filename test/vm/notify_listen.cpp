// Plays systemd's side of Type=notify for the VM test of `rankslam run`: binds an AF_UNIX
// datagram socket at PATH (for NOTIFY_SOCKET), prints "listening" once bound, then each
// datagram received as one line, until SIGTERM or SIGINT.
//
//   notify_listen PATH
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: notify_listen PATH\n");
    return 2;
  }
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  sockaddr_un address{};
  address.sun_family = AF_UNIX;
  if (fd < 0 || std::strlen(argv[1]) >= sizeof address.sun_path) {
    std::fprintf(stderr, "notify_listen: no socket for %s\n", argv[1]);
    return 1;
  }
  std::strncpy(address.sun_path, argv[1], sizeof address.sun_path - 1);
  ::unlink(argv[1]);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    std::fprintf(stderr, "notify_listen: bind %s: %s\n", argv[1], std::strerror(errno));
    return 1;
  }
  std::printf("listening\n");
  std::fflush(stdout);
  char buffer[4096];
  for (;;) {
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n < 0) {
      if (errno == EINTR) continue;
      break;
    }
    std::fwrite(buffer, 1, static_cast<std::size_t>(n), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }
  return 0;
}
