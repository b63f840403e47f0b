// Named camera presets: sensor parameters of real cameras from their published
// EMVA 1288 (or photon-transfer) data. Each preset is TOML text applied on top
// of the defaults (or of a config file); presets.cc cites the source of every
// number and says which values are assumptions because the source lacks them.
//
//   camsim config --preset NAME     prints one
//   camsim run --preset NAME ...    runs with one (a --config file and --set
//                                   overrides are applied after it)
//   camsim emva --preset NAME       measures one back (host_tools/emva_measure.h)
#pragma once

#include <string>
#include <vector>

#include "host_tools/config.h"

namespace camsim::host {

struct Preset {
  const char* name;
  const char* summary;  // one line: camera, sensor, source
  const char* toml;     // the preset's configuration, with its citations as comments
  // The source's EMVA 1288 saturation capacity, electrons, from which the
  // TOML's full_well_e is derived (presets.cc); 0 when the source gives the
  // clip itself and the TOML sets it.
  double saturation_e;
};

const std::vector<Preset>& Presets();
// nullptr when there is no preset of that name.
const Preset* FindPreset(const std::string& name);
// Applies a preset to *config; false (and *error names the preset) when unknown.
bool ApplyPreset(const std::string& name, RunConfig* config, Origins* origins, std::string* error);

}  // namespace camsim::host
