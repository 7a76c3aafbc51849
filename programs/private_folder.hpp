// A private folder under /tmp (mkdtemp: mode 0700, a new name) for the files of one run of
// `oegw sim` or `oegw demo`, removed with everything in it when the object goes: nothing is left
// behind, and nothing of the cab controller's (its store, its control socket) is touched.
#pragma once

#include <stdlib.h>

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

namespace oegw::programs {

class PrivateFolder {
 public:
  // /tmp/oegw-COMMAND-XXXXXX; nullptr when it cannot be made, the reason printed
  // ("oegw COMMAND: mkdtemp: ...").
  static std::unique_ptr<PrivateFolder> make(const std::string& command) {
    std::string name = "/tmp/oegw-" + command + "-XXXXXX";
    if (::mkdtemp(name.data()) == nullptr) {
      std::perror(("oegw " + command + ": mkdtemp").c_str());
      return nullptr;
    }
    return std::unique_ptr<PrivateFolder>(new PrivateFolder(name));
  }
  ~PrivateFolder() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  PrivateFolder(const PrivateFolder&) = delete;
  PrivateFolder& operator=(const PrivateFolder&) = delete;

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  explicit PrivateFolder(std::filesystem::path p) : path_(std::move(p)) {}
  std::filesystem::path path_;
};

}  // namespace oegw::programs
