#include "canopen/301/storage.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace oegw::canopen {

namespace {

constexpr std::uint16_t kStoreIndex = 0x1010;
constexpr std::uint16_t kRestoreIndex = 0x1011;
constexpr const char* kMagic = "OEGW-OD-STORE 1\n";

constexpr std::uint16_t kErrorHistory = 0x1003;

// 1010h/1011h: commands, reading 1 again after each accepted signature.
bool signature_object(std::uint16_t index) { return index == kStoreIndex || index == kRestoreIndex; }
// Never stored nor loaded: the commands, and the error history (CiA 301 §7.5.2.5: the errors
// that occurred; a stored count would come back after a reset without its entries).
bool excluded(std::uint16_t index) { return signature_object(index) || index == kErrorHistory; }

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// Parses exactly `s` as hex into `out` (whole bytes).
bool parse_hex(std::string_view s, std::vector<std::uint8_t>& out) {
  if (s.size() % 2 != 0) return false;
  out.clear();
  for (std::size_t i = 0; i < s.size(); i += 2) {
    const int hi = hex_digit(s[i]);
    const int lo = hex_digit(s[i + 1]);
    if (hi < 0 || lo < 0) return false;
    out.push_back(static_cast<std::uint8_t>(hi * 16 + lo));
  }
  return true;
}

bool parse_hex_number(std::string_view s, std::size_t digits, std::uint32_t& v) {
  if (s.size() != digits) return false;
  v = 0;
  for (char c : s) {
    const int d = hex_digit(c);
    if (d < 0) return false;
    v = v * 16 + static_cast<std::uint32_t>(d);
  }
  return true;
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> parts;
  std::size_t pos = 0;
  while (pos <= line.size()) {
    const std::size_t sp = line.find(' ', pos);
    const std::size_t end = sp == std::string_view::npos ? line.size() : sp;
    parts.push_back(line.substr(pos, end - pos));
    if (sp == std::string_view::npos) break;
    pos = sp + 1;
  }
  return parts;
}

std::string errno_text(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

bool fsync_dir(const std::filesystem::path& dir, std::string& error) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) {
    error = errno_text("open directory");
    return false;
  }
  const bool ok = ::fsync(fd) == 0;
  if (!ok) error = errno_text("fsync directory");
  ::close(fd);
  return ok;
}

}  // namespace

std::uint32_t ParameterStore::crc32(const std::string& bytes) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) c = table[(c ^ b) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

std::string ParameterStore::serialize(const Entries& entries) {
  std::string out = kMagic;
  char buf[16];
  for (const auto& [key, value] : entries) {
    std::snprintf(buf, sizeof buf, "%04X %02X ", key.first, key.second);
    out += buf;
    if (value.empty()) out += '-';
    for (std::uint8_t b : value) {
      std::snprintf(buf, sizeof buf, "%02X", b);
      out += buf;
    }
    out += '\n';
  }
  const std::uint32_t crc = crc32(out);
  std::snprintf(buf, sizeof buf, "%08X", crc);
  out += "END " + std::to_string(entries.size()) + " " + buf + "\n";
  return out;
}

std::optional<ParameterStore::Entries> ParameterStore::parse(const std::string& text, std::string& error) {
  const std::string magic = kMagic;
  if (text.compare(0, magic.size(), magic) != 0) {
    error = "not a store file (bad header)";
    return std::nullopt;
  }
  Entries entries;
  std::size_t pos = magic.size();
  while (true) {
    const std::size_t nl = text.find('\n', pos);
    if (nl == std::string::npos) {
      error = "truncated store file (no END line)";
      return std::nullopt;
    }
    const std::string_view line(text.data() + pos, nl - pos);
    const auto parts = split(line);
    if (!parts.empty() && parts[0] == "END") {
      std::uint32_t crc = 0;
      if (parts.size() != 3 || !parse_hex_number(parts[2], 8, crc)) {
        error = "malformed END line";
        return std::nullopt;
      }
      if (parts[1] != std::to_string(entries.size())) {
        error = "entry count mismatch";
        return std::nullopt;
      }
      if (crc != crc32(text.substr(0, pos))) {
        error = "CRC mismatch";
        return std::nullopt;
      }
      if (nl + 1 != text.size()) {
        error = "trailing data after END line";
        return std::nullopt;
      }
      return entries;
    }
    std::uint32_t index = 0;
    std::uint32_t sub = 0;
    std::vector<std::uint8_t> value;
    if (parts.size() != 3 || !parse_hex_number(parts[0], 4, index) || !parse_hex_number(parts[1], 2, sub) ||
        !(parts[2] == "-" || (!parts[2].empty() && parse_hex(parts[2], value)))) {
      error = "malformed entry line: " + std::string(line.substr(0, 40));
      return std::nullopt;
    }
    if (!entries.emplace(Key{static_cast<std::uint16_t>(index), static_cast<std::uint8_t>(sub)}, std::move(value))
             .second) {
      error = "duplicate entry";
      return std::nullopt;
    }
    pos = nl + 1;
  }
}

ParameterStore::ParameterStore(ObjectDictionary& od, std::filesystem::path file) : od_(od), file_(std::move(file)) {
  for (const std::uint16_t index : {kStoreIndex, kRestoreIndex}) {
    Object* obj = od_.find(index);
    if (obj == nullptr) {
      obj = &od_.add_array(index, index == kStoreIndex ? "Store parameters" : "Restore default parameters",
                           DataType::Unsigned32, Access::ReadWrite, 3, encode<std::uint32_t>(1));
    }
    subs_ += obj->add_write_hook([this, index](Object&, std::uint8_t sub, std::span<const std::uint8_t> bytes, Origin) {
      if (sub == 0) return SdoAbortCode::None;
      const std::uint32_t expected = index == kStoreIndex ? kSaveSignature : kLoadSignature;
      if (bytes.size() != 4 || get_u32(bytes.data()) != expected) return SdoAbortCode::CannotTransfer;
      if (sub > 3) return SdoAbortCode::CannotTransfer;  // manufacturer-specific groups: none
      const auto g = static_cast<Group>(sub);
      return index == kStoreIndex ? save(g) : restore_defaults(g);
    });
  }
  // After an accepted signature the entry reads 1 again ("on command").
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) {
    if (sub == 0 || !signature_object(index)) return;
    if (SubObject* s = od_.find(index, sub)) s->value = encode<std::uint32_t>(1);
  });
}

std::filesystem::path ParameterStore::temp_path() const {
  std::filesystem::path p = file_;
  p += ".tmp";
  return p;
}

std::pair<std::uint16_t, std::uint16_t> ParameterStore::range(Group g) {
  switch (g) {
    case Group::Communication: return {0x1000, 0x1FFF};
    case Group::Application: return {0x6000, 0x9FFF};
    case Group::All: break;
  }
  return {0x0000, 0xFFFF};
}

PlainFile read_plain_file(const std::filesystem::path& file) {
  PlainFile r;
  const int fd = ::open(file.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    if (errno == ENOENT) return r;
    r.state = PlainFile::State::Refused;
    r.error = errno == ELOOP ? "is a symbolic link (never followed: the store is a plain file the gateway replaces)"
                             : errno_text("cannot be opened");
    return r;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    r.state = PlainFile::State::Refused;
    r.error = "is not a regular file";
    ::close(fd);
    return r;
  }
  char buf[4096];
  while (true) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      r.state = PlainFile::State::Refused;
      r.error = errno_text("cannot be read");
      r.text.clear();
      ::close(fd);
      return r;
    }
    if (n == 0) break;
    r.text.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  r.state = PlainFile::State::Read;
  return r;
}

ParameterStore::Stored ParameterStore::read_file() const {
  Stored out;
  PlainFile f = read_plain_file(file_);
  seen_ = f;
  if (f.state == PlainFile::State::Absent) return out;
  out.present = true;
  if (f.state == PlainFile::State::Refused) {
    out.link = f.error.rfind("is a symbolic link", 0) == 0;
    out.error = std::move(f.error);
    return out;
  }
  out.entries = parse(f.text, out.error);
  return out;
}

SdoAbortCode ParameterStore::refuse_on(const Stored& stored, Group group, const char* what) {
  if (!stored.present || stored.entries) return SdoAbortCode::None;
  if (group == Group::All && !stored.link) return SdoAbortCode::None;  // replaces the whole file
  last_error_ = file_.string() + ": " + stored.error + "; " + what +
                (stored.link ? " refused"
                             : " of one group refused: the other groups are stored there and cannot be read (sub 1, "
                               "all groups, replaces the file)");
  return SdoAbortCode::HardwareError;
}

ParameterStore::LoadResult ParameterStore::load(std::uint16_t first, std::uint16_t last) {
  LoadResult r;
  Stored stored = read_file();
  if (stored.present && !stored.entries) {
    r.file_present = true;
    r.error = file_.string() + ": " + stored.error + "; stored parameters ignored";
    last_error_ = r.error;
    return r;
  }
  r.ok = true;
  if (!stored.present) return r;
  r.file_present = true;
  for (const auto& [key, value] : *stored.entries) {
    if (key.first < first || key.first > last) continue;
    SubObject* s = od_.find(key.first, key.second);
    const std::size_t n = s == nullptr ? 0 : fixed_size(s->type);
    if (s == nullptr || excluded(key.first) || !writable(s->access) || (n != 0 && value.size() != n) ||
        (n == 0 && value.size() > s->max_size)) {
      ++r.skipped;
      continue;
    }
    s->value = value;
    ++r.applied;
  }
  return r;
}

SdoAbortCode ParameterStore::save(Group group) {
  const Stored stored = read_file();
  if (const SdoAbortCode refused = refuse_on(stored, group, "save"); refused != SdoAbortCode::None) return refused;
  Entries entries = stored.entries.value_or(Entries{});  // sub 1 over a refused file replaces it
  const auto [first, last] = range(group);               // plain copies below: clang 14 cannot capture bindings
  const std::uint16_t lo = first, hi = last;
  std::erase_if(entries, [lo, hi](const auto& e) { return e.first.first >= lo && e.first.first <= hi; });
  for (const auto& [index, obj] : od_.objects()) {
    if (index < first || index > last || excluded(index)) continue;
    // Only what differs from the default is stored. A value left at its default follows the
    // default, which matters for the COB-IDs whose default is "function code + node-ID": after
    // an LSS node-ID change (CiA 305) they must move with the node-ID, not come back absolute.
    for (const auto& [sub, s] : obj.subs())
      if (writable(s.access) && s.value != s.default_value) entries[{index, sub}] = s.value;
  }
  return write_atomically(serialize(entries)) ? SdoAbortCode::None : SdoAbortCode::HardwareError;
}

SdoAbortCode ParameterStore::restore_defaults(Group group) {
  Stored stored = read_file();
  if (const SdoAbortCode refused = refuse_on(stored, group, "restore"); refused != SdoAbortCode::None) return refused;
  if (!stored.present) return SdoAbortCode::None;  // nothing stored: defaults already
  if (group == Group::All) return remove_atomically() ? SdoAbortCode::None : SdoAbortCode::HardwareError;
  const auto [first, last] = range(group);
  const std::uint16_t lo = first, hi = last;
  std::erase_if(*stored.entries, [lo, hi](const auto& e) { return e.first.first >= lo && e.first.first <= hi; });
  return write_atomically(serialize(*stored.entries)) ? SdoAbortCode::None : SdoAbortCode::HardwareError;
}

bool write_file_atomically(const std::filesystem::path& file, const std::string& text, std::string& error) {
  struct stat st {};
  if (::lstat(file.c_str(), &st) == 0 && S_ISLNK(st.st_mode)) {
    error = file.string() + " is a symbolic link: not replaced (the store is a plain file)";
    return false;
  }
  const std::filesystem::path tmp = file.string() + ".tmp";
  constexpr int kCreate = O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC;
  int fd = ::open(tmp.c_str(), kCreate, 0644);
  if (fd < 0 && errno == EEXIST) {
    // Left by a crash between its creation and the rename, or planted: removed (a link is
    // removed, never followed), then created afresh. Created again meanwhile: refused below.
    (void)::unlink(tmp.c_str());
    fd = ::open(tmp.c_str(), kCreate, 0644);
  }
  if (fd < 0) {
    error = errno_text("create temp file") + " (" + tmp.string() + ")";
    return false;
  }
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = errno_text("write temp file");
      ::close(fd);
      ::unlink(tmp.c_str());
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    error = errno_text("fsync temp file");
    ::close(fd);
    ::unlink(tmp.c_str());
    return false;
  }
  if (::close(fd) != 0) {
    error = errno_text("close temp file");
    ::unlink(tmp.c_str());
    return false;
  }
  if (::rename(tmp.c_str(), file.c_str()) != 0) {
    error = errno_text("rename temp file");
    ::unlink(tmp.c_str());
    return false;
  }
  return fsync_dir(file.parent_path(), error);
}

bool ParameterStore::write_atomically(const std::string& text) {
  if (!write_file_atomically(file_, text, last_error_)) {
    seen_ = read_plain_file(file_);  // the rename may have been done (the directory's fsync failed)
    return false;
  }
  seen_ = PlainFile{.state = PlainFile::State::Read, .text = text, .error = {}};
  return true;
}

bool ParameterStore::remove_atomically() {
  if (::unlink(file_.c_str()) != 0 && errno != ENOENT) {
    last_error_ = errno_text("remove store file");
    return false;
  }
  seen_ = PlainFile{};
  return fsync_dir(file_.parent_path(), last_error_);
}

}  // namespace oegw::canopen
