//! The reference the comparator model is held against: a Schmitt trigger acting on voltages,
//! sampled. hal-sim's counter never samples its comparators (it computes their edges in phase,
//! `hal_sim::photodiode::EdgeGeometry`); the tests feed this trigger the same noise-free levels
//! and require the same states.

use hal_sim::photodiode::ChannelConfig;

/// A comparator with hysteresis acting on voltages (a Schmitt trigger).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SchmittTrigger {
    high_above_v: f64,
    low_below_v: f64,
    state: bool,
}

impl SchmittTrigger {
    /// The comparator of `channel`, starting in `initial_state`.
    pub fn new(channel: &ChannelConfig, initial_state: bool) -> Self {
        let c = &channel.comparator;
        let threshold_v = channel.mid_level_v + c.threshold_offset_v;
        Self {
            high_above_v: threshold_v + c.hysteresis_v / 2.0,
            low_below_v: threshold_v - c.hysteresis_v / 2.0,
            state: initial_state,
        }
    }

    /// Feed one input level; returns the output.
    pub fn update(&mut self, v: f64) -> bool {
        if v > self.high_above_v {
            self.state = true;
        } else if v < self.low_below_v {
            self.state = false;
        }
        self.state
    }
}
