// Why a publishing transport (DDS, LCM) cannot be opened: the configuration, or the machine as
// it is now (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs).
#pragma once

#include <stdexcept>

namespace oegw::publish {

class PublishError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A setting that cannot be applied. what() names it: "publish.dds.domain: cannot create domain 7: ...".
// `oegw run` refuses to start with it.
class PublishConfigError : public PublishError {
 public:
  using PublishError::PublishError;
};

// The settings are right but the machine cannot carry the transport now: no route for the LCM
// group, the interface publish.dds.network names missing, liblcm's self-test never sees its own
// message. what() names the setting and the reason. `oegw run` runs without the transport and
// opens it again later (gateway/publisher_link.hpp).
class PublishUnavailable : public PublishError {
 public:
  using PublishError::PublishError;
};

}  // namespace oegw::publish
