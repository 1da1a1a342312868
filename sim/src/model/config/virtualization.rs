//! `[virtualization]`: how ray virtualization (paper sections 3.1, 4.1 and 6.6) suspends and
//! resumes CTAs. The paper leaves these choices partly open; each is a switch so that its effect
//! on the virtualization overhead can be measured (docs/fidelity.md). They mean something only
//! with `mode.virtualization = true`; changing one without it is rejected.

use std::fmt;

use serde::{Deserialize, Serialize};

/// When a suspended CTA whose rays have all completed loads its saved state back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RestorePolicy {
    /// When it gets a CTA slot on its SM: the slot is held while the loads are in flight, and
    /// the restore latency is on the CTA's critical path after the wait for a slot.
    #[default]
    OnSlot,
    /// As soon as it is ready to resume, i.e. when the paper's RT unit injects it back into
    /// the CTA scheduler: "loads are issued to retrieve the saved state before the CTA is
    /// scheduled to an SM" (paper section 5). The loads overlap the wait for a slot; a CTA whose
    /// state is back runs as soon as it gets one.
    OnReady,
}

impl RestorePolicy {
    /// The name used in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            RestorePolicy::OnSlot => "on_slot",
            RestorePolicy::OnReady => "on_ready",
        }
    }
}

impl fmt::Display for RestorePolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// When a CTA whose live warps all wait for or are in the RT unit is suspended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SuspendPolicy {
    /// At once: "once all threads in the CTA submit their rays, the CTA can be terminated"
    /// (paper section 4.1), whether or not another CTA needs its slot.
    #[default]
    Eager,
    /// Only when its slot is wanted: after the CTA dispatch of a cycle, an SM suspends as many
    /// such CTAs as it needs slots for the CTAs still pending at the CTA scheduler that fit its
    /// ray budget and for its own suspended CTAs ready to resume (slots of CTAs already
    /// suspending count as free). A CTA nobody needs the slot of keeps it, as in the baseline,
    /// and saves no state.
    OnDemand,
}

impl SuspendPolicy {
    /// The name used in configuration files.
    pub fn name(self) -> &'static str {
        match self {
            SuspendPolicy::Eager => "eager",
            SuspendPolicy::OnDemand => "on_demand",
        }
    }
}

impl fmt::Display for SuspendPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// `[virtualization]`: the modelling switches of ray virtualization.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VirtualizationConfig {
    /// When a ready CTA's state is loaded back (`on_slot`, the default; `on_ready`, the paper's
    /// Vulkan-Sim model).
    pub restore: RestorePolicy,
    /// When a CTA is suspended (`eager`, the default; `on_demand`).
    pub suspend: SuspendPolicy,
    /// Whether saving and restoring a CTA's state moves `SimConfig::cta_state_bytes` through
    /// the memory system (true). False is an idealisation for attributing the overhead: a
    /// suspended CTA leaves its slot at once and a resumed one runs at once, with no traffic.
    pub state_traffic: bool,
}

impl Default for VirtualizationConfig {
    fn default() -> Self {
        VirtualizationConfig {
            restore: RestorePolicy::OnSlot,
            suspend: SuspendPolicy::Eager,
            state_traffic: true,
        }
    }
}

impl VirtualizationConfig {
    /// The first key that differs from its default, with its value (for rejecting the section
    /// when ray virtualization is off).
    pub fn changed_key(&self) -> Option<(&'static str, String)> {
        let d = VirtualizationConfig::default();
        if self.restore != d.restore {
            return Some(("virtualization.restore", self.restore.to_string()));
        }
        if self.suspend != d.suspend {
            return Some(("virtualization.suspend", self.suspend.to_string()));
        }
        if self.state_traffic != d.state_traffic {
            return Some((
                "virtualization.state_traffic",
                self.state_traffic.to_string(),
            ));
        }
        None
    }
}
