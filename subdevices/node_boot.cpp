#include "subdevices/node_boot.hpp"

#include <cstdio>

namespace oegw::subdevices {

using canopen::SdoAbortCode;

namespace {

std::string hex32(std::uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08Xh", v);
  return b;
}

std::string obj(std::uint16_t index, std::uint8_t sub) {
  char b[16];
  std::snprintf(b, sizeof b, "%04Xh:%02X", index, sub);
  return b;
}

// A check of a UNSIGNED32 answer against an expected value (CiA 302-2 identity check), in the
// bits of `mask`; the value read is kept in `keep` when given.
std::function<std::string(const std::vector<std::uint8_t>&)> expect_u32(std::uint16_t index, std::uint8_t sub,
                                                                        std::optional<std::uint32_t> want,
                                                                        std::optional<std::uint32_t>* keep = nullptr,
                                                                        std::uint32_t mask = 0xFFFFFFFFu) {
  return [index, sub, want, keep, mask](const std::vector<std::uint8_t>& d) -> std::string {
    if (d.size() != 4) return obj(index, sub) + " answered " + std::to_string(d.size()) + " bytes, expected 4";
    const std::uint32_t got = canopen::get_u32(d.data());
    if (keep != nullptr) *keep = got;
    if (!want || (got & mask) == (*want & mask)) return {};
    if (mask == 0xFFFFFFFFu)
      return obj(index, sub) + " is " + hex32(got) + ", the configuration expects " + hex32(*want);
    char b[160];
    std::snprintf(b, sizeof b,
                  "%s is %08Xh: major revision %04Xh, the configuration expects %04Xh (from %08Xh; the minor revision "
                  "is not compared)",
                  obj(index, sub).c_str(), got, got >> 16, *want >> 16, *want);
    return b;
  };
}

// A VISIBLE_STRING answer (CiA 301 §7.1.6.3), kept readable: up to the first NUL, at most
// NodeDiagnostics::kMaxText characters, non-printable ones as '?'.
std::function<std::string(const std::vector<std::uint8_t>&)> keep_text(std::optional<std::string>* keep) {
  return [keep](const std::vector<std::uint8_t>& d) -> std::string {
    std::string t;
    for (const std::uint8_t c : d) {
      if (c == 0 || t.size() == NodeDiagnostics::kMaxText) break;
      t.push_back(c >= 0x20 && c < 0x7F ? static_cast<char>(c) : '?');
    }
    *keep = std::move(t);
    return {};
  };
}

std::string show(const std::optional<std::uint32_t>& v) { return v ? hex32(*v) : "-"; }
std::string show(const std::optional<std::string>& v) { return v ? "\"" + *v + "\"" : "-"; }

std::optional<std::uint32_t> pick(std::optional<std::uint32_t> configured, std::optional<std::uint32_t> driver) {
  return configured ? configured : driver;
}

}  // namespace

std::string NodeDiagnostics::describe() const {
  char reg[8] = "-";
  if (error_register) std::snprintf(reg, sizeof reg, "%02Xh", static_cast<unsigned>(*error_register));
  return "vendor " + show(vendor_id) + ", product " + show(product_code) + ", revision " + show(revision) +
         ", serial " + show(serial) + ", name " + show(device_name) + ", hardware " + show(hardware_version) +
         ", software " + show(software_version) + ", error register " + reg;
}

void NodeBoot::plan(const NodeSettings& settings, Driver& driver) {
  driver_ = &driver;
  diag_ = {};
  error_register_answer_.clear();
  steps_.clear();
  next_ = 0;
  using Kind = Step::Kind;
  add_identity_steps(settings);
  add_diagnostic_steps();
  steps_.push_back({Kind::Diagnostics, 0, 0, {}, "diagnostics", {}});
  driver_->begin_boot();
  steps_.push_back({Kind::DriverReads, 0, 0, {}, "driver reads", {}});
  if (settings.heartbeat_ms != 0)
    steps_.push_back(
        {Kind::Write, 0x1017, 0, canopen::encode<std::uint16_t>(settings.heartbeat_ms), "producer heartbeat", {}});
  steps_.push_back({Kind::DriverWrites, 0, 0, {}, "driver configuration", {}});
  for (const SdoWrite& w : settings.sdo) steps_.push_back({Kind::Write, w.index, w.sub, w.data, w.what, {}});
}

void NodeBoot::add_identity_steps(const NodeSettings& settings) {
  // CiA 302-2 boot-up: device type and identity first.
  const ExpectedIdentity drv = driver_->expected_identity();
  const ExpectedIdentity& cfg = settings.identity;
  using Kind = Step::Kind;
  steps_.push_back({Kind::Read,
                    0x1000,
                    0,
                    {},
                    "device type",
                    expect_u32(0x1000, 0, pick(cfg.device_type, drv.device_type), &diag_.device_type)});
  const std::optional<std::uint32_t> ident[4] = {pick(cfg.vendor_id, drv.vendor_id),
                                                 pick(cfg.product_code, drv.product_code),
                                                 pick(cfg.revision, drv.revision), pick(cfg.serial, drv.serial)};
  std::optional<std::uint32_t>* keep[4] = {&diag_.vendor_id, &diag_.product_code, &diag_.revision, &diag_.serial};
  static const char* const names[4] = {"vendor-ID", "product code", "revision number", "serial number"};
  for (std::uint8_t sub = 1; sub <= 4; ++sub) {
    const std::uint32_t mask = sub == 3 && !settings.exact_revision ? 0xFFFF0000u : 0xFFFFFFFFu;
    Step st{Kind::Read, 0x1018, sub, {}, names[sub - 1], expect_u32(0x1018, sub, ident[sub - 1], keep[sub - 1], mask)};
    st.optional = !ident[sub - 1];  // CiA 301 §7.5.2.13: only sub 1 is mandatory
    steps_.push_back(std::move(st));
  }
}

void NodeBoot::add_diagnostic_steps() {
  using Kind = Step::Kind;
  const std::pair<std::uint16_t, std::optional<std::string>*> texts[] = {{0x1008, &diag_.device_name},
                                                                         {0x1009, &diag_.hardware_version},
                                                                         {0x100A, &diag_.software_version}};
  static const char* const names[3] = {"manufacturer device name", "manufacturer hardware version",
                                       "manufacturer software version"};
  for (std::size_t i = 0; i < 3; ++i) {
    Step st{Kind::Read, texts[i].first, 0, {}, names[i], keep_text(texts[i].second)};
    st.optional = true;
    steps_.push_back(std::move(st));
  }
  std::optional<std::uint8_t>* reg = &diag_.error_register;
  std::vector<std::uint8_t>* answer = &error_register_answer_;
  // CiA 301 §7.5.2.2: 1001h is UNSIGNED8; a device document may give it otherwise (the
  // Novotechnik's §4.1 "1001 Error register Unsigned16"): 1 or 2 bytes are taken, the CiA 301
  // bits are the low byte (little endian, CiA 301 §7.1.2); the driver gets the answer as it came.
  Step st{Kind::Read,
          0x1001,
          0,
          {},
          "error register",
          [reg, answer](const std::vector<std::uint8_t>& d) -> std::string {
            if (d.size() != 1 && d.size() != 2)
              return obj(0x1001, 0) + " answered " + std::to_string(d.size()) + " bytes, expected 1 (or 2)";
            *reg = d[0];
            *answer = d;
            return {};
          }};
  st.optional = true;
  steps_.push_back(std::move(st));
}

NodeBoot::Next NodeBoot::advance() {
  using Kind = Step::Kind;
  while (next_ < steps_.size()) {
    switch (steps_[next_].kind) {
      case Kind::Read:
      case Kind::Write: return Next::Request;
      case Kind::Diagnostics: ++next_; return Next::Diagnostics;
      case Kind::DriverWrites: {
        // In the marker's place (the configuration may depend on what the boot reads found).
        std::vector<Step> writes;
        for (const SdoWrite& w : driver_->configuration()) {
          writes.push_back({Kind::Write, w.index, w.sub, w.data, w.what, {}});
          writes.back().driver_write = true;
        }
        const auto at = steps_.begin() + static_cast<std::ptrdiff_t>(next_);
        steps_.insert(steps_.erase(at), writes.begin(), writes.end());
        break;
      }
      case Kind::DriverReads: {
        // The driver's next round of reads runs before this marker, which is asked again
        // afterwards. No more reads: on to the writes.
        auto reads = driver_->boot_reads();
        if (reads.empty()) {
          ++next_;
          break;
        }
        Driver* d = driver_;
        std::vector<Step> round;
        for (const auto& [index, sub] : reads) {
          const std::uint16_t i = index;
          const std::uint8_t s = sub;
          Step st{Kind::Read, index, sub, {}, "driver read", [d, i, s](const std::vector<std::uint8_t>& data) {
                    std::string error;
                    if (!d->on_boot_read(i, s, data, error)) return obj(i, s) + ": " + error;
                    return std::string{};
                  }};
          st.driver_read = true;
          round.push_back(std::move(st));
        }
        steps_.insert(steps_.begin() + static_cast<std::ptrdiff_t>(next_), round.begin(), round.end());
        return Next::Request;
      }
    }
  }
  return Next::Done;
}

std::string NodeBoot::check_error_register() {
  // 1001h is read once per boot, in the diagnostics: a driver whose faults it decides
  // (Driver::boot_reads) takes this answer and does not read it again. Absent (refused): the
  // driver reads it itself and decides what its refusal means.
  if (!diag_.error_register) return {};
  std::string error;
  if (driver_->on_boot_read(0x1001, 0, error_register_answer_, error)) return {};
  return obj(0x1001, 0) + ": " + error;
}

NodeBoot::Verdict NodeBoot::on_answer(SdoAbortCode code, const std::vector<std::uint8_t>& data) {
  Step& st = steps_[next_];
  const std::string where = std::string(st.kind == Step::Kind::Read ? "reading " : "writing ") + obj(st.index, st.sub) +
                            (st.what.empty() ? "" : " (" + st.what + ")");
  if (code == SdoAbortCode::Timeout) return {Verdict::Kind::NoAnswer, where + ": no answer (SDO timeout)"};
  if (code != SdoAbortCode::None && st.optional) {
    ++next_;  // not present
    return {};
  }
  if (code != SdoAbortCode::None && st.driver_read && driver_->on_boot_read_abort(st.index, st.sub, code)) {
    ++next_;  // the driver can do without this object
    return {};
  }
  if (code != SdoAbortCode::None && st.driver_write) {
    if (auto instead = driver_->instead_of_refused(SdoWrite{st.index, st.sub, st.data, st.what}, code)) {
      st.index = instead->index;
      st.sub = instead->sub;
      st.data = instead->data;
      st.what = instead->what;
      st.driver_write = false;  // one alternative: refused too, the node is refused
      return {};
    }
  }
  if (code != SdoAbortCode::None)
    return {Verdict::Kind::Refused,
            where + ": abort " + hex32(static_cast<std::uint32_t>(code)) + " " + std::string(canopen::to_string(code))};
  if (st.check) {
    if (std::string error = st.check(data); !error.empty()) return {Verdict::Kind::Refused, std::move(error)};
  }
  ++next_;
  return {};
}

std::vector<SdoWrite> NodeBoot::writes() const {
  std::vector<SdoWrite> out;
  for (const Step& st : steps_)
    if (st.kind == Step::Kind::Write) out.push_back({st.index, st.sub, st.data, {}});
  return out;
}

}  // namespace oegw::subdevices
