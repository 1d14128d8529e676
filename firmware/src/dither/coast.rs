//! The drive tick without the controller: what the board's drive tick needs to keep the DAC
//! going while the controller cannot run (a flash operation stalls every fetch from flash, and
//! the controller's code lives there), and to hand the gap over afterwards.
//!
//! Between two loop updates the controller's DAC codes are exactly [`Drive::dac_code_at_tick`]
//! of its [`DitherController::drive`] (the controller's contract, checked tick by tick in this
//! module's `tests` bench). So a tick that cannot reach the controller writes the code the
//! controller would have written had no loop update fallen on it: the drive in force,
//! continued. [`Coast::code`] is that tick, [`Coast::hand_over`] tells the controller how many
//! it missed ([`DitherController::coast`]) before its next tick, [`Coast::follow`] keeps the
//! drive and the tick index current after each tick the controller ran.
//!
//! On the board the coasting tick runs from RAM (`board::ram`, with the sine's table in RAM:
//! `crate::math::cossin`), so a store's word programming (16 us typical, 100 us at most) and a
//! sector erase (1 to 2 s) leave the dither driven: the resonator sees the drive its loops had
//! set, open loop for the stall, and the loops take over again after it. The simulated board
//! runs the same code (`hal-sim`'s `drive_loop`).
//!
//! Cost: one `cossin`, one 64-bit product and a few adds per coasted tick (~60 instructions),
//! and 28 bytes of state.

use super::{DitherConfig, DitherController, Drive};

/// The drive in force and the controller's tick count, kept by the drive tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coast {
    /// The drive in force.
    drive: Drive,
    /// The controller's index of the next pick-off sample (the tick being handled).
    next_tick: u32,
    /// Ticks run without the controller since it last ran.
    coasted: u32,
}

impl Coast {
    /// Following `controller` from its present state.
    pub fn new(controller: &DitherController) -> Self {
        Self {
            drive: controller.drive(),
            next_tick: controller.tick(),
            coasted: 0,
        }
    }

    /// A tick without the controller: the DAC code of the next tick (the drive in force,
    /// continued); counts the tick for [`Self::hand_over`].
    #[inline(always)]
    pub fn code(&mut self) -> u16 {
        self.next_tick = self.next_tick.wrapping_add(1);
        self.coasted = self.coasted.wrapping_add(1);
        self.drive.dac_code_at_tick(self.next_tick)
    }

    /// Ticks run without the controller since it last ran.
    pub fn coasted(&self) -> u32 {
        self.coasted
    }

    /// Before the controller's next tick: the ticks it missed, handed to
    /// [`DitherController::coast`].
    #[inline]
    pub fn hand_over(&mut self, controller: &mut DitherController, config: &DitherConfig) {
        if self.coasted > 0 {
            controller.coast(config, self.coasted);
            self.coasted = 0;
        }
    }

    /// After a tick the controller ran: its drive and tick index.
    #[inline]
    pub fn follow(&mut self, controller: &DitherController) {
        self.drive = controller.drive();
        self.next_tick = controller.tick();
    }
}
