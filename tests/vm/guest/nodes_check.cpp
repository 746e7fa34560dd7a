// Guest program: the device nodes a VM test needs exist and answer their basic query (VIDIOC_QUERYCAP
// for a video node, MEDIA_IOC_DEVICE_INFO for a media node). It proves the VM plumbing (kernel,
// modules, devtmpfs) before any driver test; prints one PASS or FAIL line per node.
// usage: vm_nodes_check <device-node>...
#include <fcntl.h>
#include <linux/media.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace {

bool check_node(const char* path) {
  const int fd = ::open(path, O_RDWR | O_NONBLOCK);
  if (fd < 0) {
    std::printf("FAIL nodes %s: open: %s\n", path, std::strerror(errno));
    return false;
  }
  bool ok = false;
  if (std::strncmp(path, "/dev/media", 10) == 0) {
    media_device_info info{};
    if (::ioctl(fd, MEDIA_IOC_DEVICE_INFO, &info) == 0) {
      std::printf("PASS nodes %s: media driver %s, model %s\n", path, info.driver, info.model);
      ok = true;
    } else {
      std::printf("FAIL nodes %s: MEDIA_IOC_DEVICE_INFO: %s\n", path, std::strerror(errno));
    }
  } else {
    v4l2_capability cap{};
    if (::ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0) {
      std::printf("PASS nodes %s: driver %s, card %s\n", path, reinterpret_cast<const char*>(cap.driver),
                  reinterpret_cast<const char*>(cap.card));
      ok = true;
    } else {
      std::printf("FAIL nodes %s: VIDIOC_QUERYCAP: %s\n", path, std::strerror(errno));
    }
  }
  ::close(fd);
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::printf("FAIL nodes: usage: vm_nodes_check <device-node>...\n");
    return 2;
  }
  int failures = 0;
  for (int i = 1; i < argc; ++i) failures += check_node(argv[i]) ? 0 : 1;
  return failures == 0 ? 0 : 1;
}
