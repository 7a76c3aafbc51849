// The CiA 852 functional-element names as the mapping layer and its users spell them
// (mapping::FeId, mapping::fe_fields ...). The table itself: profiles/cia852/fe_table.hpp.
#pragma once

#include "profiles/cia852/fe_table.hpp"

namespace oegw::mapping {

using cia852::fe_fields;
using cia852::fe_kind_from_string;
using cia852::fe_name;
using cia852::FeField;
using cia852::FeId;
using cia852::FeKind;
using cia852::find_fe_field;
using cia852::is_input;
using cia852::max_instances;
using cia852::to_string;

}  // namespace oegw::mapping
