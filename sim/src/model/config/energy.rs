//! `[energy]`: which coefficients the energy model (`sim/src/model/energy/`, docs/energy.md)
//! evaluates a run's statistics with, and the clock that turns cycles into seconds. The energy
//! model observes the statistics after a run; nothing here changes what is simulated.
//!
//! The section is written into a configuration's TOML ([`super::SimConfig::to_toml`]) only when
//! it differs from its defaults, so adding it changed neither the `config` statistic of any
//! existing run nor any sweep's result key.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::{in_range, ConfigError};

/// A named set of energy coefficients (docs/energy.md lists every coefficient and its source).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CoefficientSet {
    /// The paper's accounting: AccelWattch's PTX fit for the QV100 (memory events and the time
    /// terms; no energy for box or triangle tests or the treelet tables, as in Vulkan-Sim).
    #[default]
    AccelwattchPtx,
    /// AccelWattch's SASS fit for the QV100, the same terms (for sensitivity).
    AccelwattchSass,
    /// CACTI-class SRAM energies scaled to the configured L1, L2 and treelet-table sizes,
    /// GDDR6 energy per bit and datapath energies of box and triangle tests; AccelWattch's time
    /// terms and interconnect flit (no physical figure in the sources).
    Physical,
}

impl CoefficientSet {
    /// Every set, in the order reports list them.
    pub const ALL: [CoefficientSet; 3] = [
        CoefficientSet::AccelwattchPtx,
        CoefficientSet::AccelwattchSass,
        CoefficientSet::Physical,
    ];

    /// The name used in configuration files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CoefficientSet::AccelwattchPtx => "accelwattch-ptx",
            CoefficientSet::AccelwattchSass => "accelwattch-sass",
            CoefficientSet::Physical => "physical",
        }
    }

    /// The set called `name`, or an error listing the valid names.
    pub fn from_name(name: &str) -> Result<CoefficientSet, String> {
        CoefficientSet::ALL
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| {
                format!(
                    "unknown energy coefficient set `{name}`; valid: {}",
                    CoefficientSet::ALL.map(CoefficientSet::name).join(", ")
                )
            })
    }
}

impl fmt::Display for CoefficientSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `[energy]`: the energy model's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EnergyConfig {
    /// The coefficient set the statistics' `energy` object is computed with
    /// (`accelwattch-ptx`, the default: the paper's accounting).
    pub coefficients: CoefficientSet,
    /// Core clock in MHz that turns cycles into seconds for the time-proportional terms (1365,
    /// the paper's Table 1 core clock).
    pub clock_mhz: u32,
}

impl Default for EnergyConfig {
    fn default() -> Self {
        EnergyConfig {
            coefficients: CoefficientSet::AccelwattchPtx,
            clock_mhz: 1365,
        }
    }
}

impl EnergyConfig {
    /// Whether every key has its default (the section is then left out of the TOML).
    pub fn is_default(&self) -> bool {
        *self == EnergyConfig::default()
    }

    /// Checks the clock's range (the coefficient set's name is checked when it is read).
    pub fn validate(&self) -> Result<(), ConfigError> {
        in_range("energy.clock_mhz", self.clock_mhz, 1..=100_000)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_listed() {
        for set in CoefficientSet::ALL {
            assert_eq!(CoefficientSet::from_name(set.name()), Ok(set));
        }
        let err = CoefficientSet::from_name("mcpat").unwrap_err();
        assert!(
            err.contains("mcpat") && err.contains("accelwattch-sass"),
            "{err}"
        );
    }

    #[test]
    fn the_clock_must_be_positive() {
        let mut e = EnergyConfig::default();
        assert!(e.validate().is_ok());
        e.clock_mhz = 0;
        let err = e.validate().unwrap_err().to_string();
        assert!(err.contains("energy.clock_mhz"), "{err}");
    }
}
