// Simulator of a generic CiA 401 node built from its EDS file (CiA 306): the dictionary is the
// one canopen::eds::build_dictionary() makes (every object, type, access, default, limit of the EDS, with
// $NODEID resolved), the PDOs are installed with the EDS defaults (1400h/1600h, 1800h/1A00h),
// and a canopen::Node runs it — so its PDO mapping can be read and changed over SDO like a real
// node's. 1000h, 1017h and 1018h come from the EDS defaults ([DeviceInfo] ProductName is the
// device name).
//
// Controls: set_input(index, sub, value) writes an input object (6000h, 6120h, 6401h, ...) as the
// device's application would (the TPDOs mapping it then send); output(index, sub) reads what the
// RPDOs wrote (6200h, 6411h, ...).
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "canopen/306/eds_reader.hpp"
#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

class Cia401Sim : public SimulatedDevice {
 public:
  // `store`: the node's parameter store (1010h/1011h) and LSS store (`store`.lss); empty: none
  // (LSS store configuration answered error 1, not supported), as the other simulators.
  Cia401Sim(const canopen::eds::File& file, NodeId node, FrameSink sink, const std::filesystem::path& store = {});
  // Loads the EDS; nullptr with `error` ("file:line: ...") if it cannot be read or parsed.
  static std::unique_ptr<Cia401Sim> from_file(const std::filesystem::path& eds_path, NodeId node, FrameSink sink,
                                              std::string& error, const std::filesystem::path& store = {});

  [[nodiscard]] std::string_view family() const override { return "cia401"; }

  // Writes an input as the device's application (Origin::Local): returns the dictionary's
  // verdict (ObjectDoesNotExist, ValueTooHigh, ...). The value is taken modulo the object's width.
  canopen::SdoAbortCode set_object(std::uint16_t index, std::uint8_t sub, std::int64_t value);
  // The current value of a numeric entry (sign-extended for signed types); nullopt if absent.
  [[nodiscard]] std::optional<std::int64_t> object_value(std::uint16_t index, std::uint8_t sub) const;

  // Driver signal names: in[k] (6000h:k), in32[k] (6120h:k), analog[k] (6401h:k); outputs
  // out[k] (6200h:k), aout[k] (6411h:k).
  bool set_input(std::string_view signal, std::int64_t value, TimePoint now) override;
  [[nodiscard]] std::optional<std::int64_t> output(std::string_view signal) const override;

  [[nodiscard]] const canopen::eds::File& eds() const { return eds_; }

 private:
  canopen::eds::File eds_;
};

}  // namespace oegw::subdevices::sim
