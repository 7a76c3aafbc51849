// The factory of each device family, implemented in that family's file pair.
#pragma once

#include <memory>
#include <string>

#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::subdevices {

std::unique_ptr<Driver> make_elobau_mfg_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                               std::string& error);  // elobau_mfg.cpp
std::unique_ptr<Driver> make_mcb402_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           std::string& error);  // mcb402.cpp
std::unique_ptr<Driver> make_novotechnik_406_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                                    std::string& error);  // novotechnik_406.cpp
std::unique_ptr<Driver> make_cia401_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           std::string& error);  // cia401.cpp

// The same, with every refusal of the options apart (driver_options.hpp).
std::unique_ptr<Driver> make_elobau_mfg_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                               OptionRefusals& refusals);
std::unique_ptr<Driver> make_mcb402_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           OptionRefusals& refusals);
std::unique_ptr<Driver> make_novotechnik_406_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                                    OptionRefusals& refusals);
std::unique_ptr<Driver> make_cia401_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           OptionRefusals& refusals);

}  // namespace oegw::subdevices
