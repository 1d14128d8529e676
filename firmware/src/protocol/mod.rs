//! The serial calibration protocol: one human-typeable command per line, one answer each.
//!
//! Bytes from the USART go through [`line::LineAssembler`] (bounded, resynchronises on `\n`),
//! [`parse::strip_checksum`] and [`parse::parse`]; the answer is exactly one line, `OK ...` or
//! `ERR <code> <text>` ([`respond`]), with a CRC suffix when the request carried one. The
//! command goes to [`execute::Executor`], which applies the access rules and hands it to its
//! group in [`commands`] (info, settings, calibration, storage, stream, access: one module and
//! one state value each); [`link`] is all the protocol sees of the device. The
//! protocol runs in the low-priority serial task: nothing here blocks or touches the turnaround
//! interrupt, whose state it changes only through staged settings.

// Input from outside the board passes here: integer arithmetic is checked, wrapping or
// saturating where an input could overflow it (the crate denies the panicking calls,
// `lib.rs`; each exception is allowed where it stands, with its reason).
#![cfg_attr(not(test), deny(clippy::arithmetic_side_effects))]

pub mod access;
pub mod cobs;
pub mod commands;
pub mod confirm;
pub mod decimal;
pub mod endpoint;
pub mod execute;
pub mod key;
pub mod le_bytes;
pub mod line;
pub mod link;
pub mod output_frame;
pub mod parse;
pub mod respond;
pub mod stream;
pub mod thermal_frame;

/// Line rate of the serial protocol (USART1, 8N1), Bd: the board's (`board::usart::BAUD`) and
/// the host tool's default for `--port`, one constant for both.
pub const SERIAL_BAUD: u32 = 460_800;

/// Why a command was refused. The discriminant is the number after `ERR`; nothing changes
/// when a command is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ErrorCode {
    /// The first word is no command of the protocol.
    UnknownCommand = 1,
    /// Missing, extra or malformed words.
    Syntax = 2,
    /// A numeric argument does not parse (decimal; the `unlock` key in hex).
    BadNumber = 3,
    /// NaN or infinite.
    NotFinite = 4,
    /// A number outside its documented range (e.g. |a| > 32767 rad/s, `cal start 0`).
    OutOfRange = 5,
    /// The `*XXXX` suffix is not 4 hex digits or not the CRC-16 of the line before it.
    BadChecksum = 6,
    /// The line was longer than `line::MAX_LINE` bytes; it was discarded unread.
    LineTooLong = 7,
    /// Non-printable bytes in the line.
    InvalidCharacters = 8,
    /// The command changes coefficients or flash: `unlock` first.
    Locked = 9,
    /// A calibration run is in progress.
    Busy = 10,
    /// Not possible in the current state (e.g. `cal accept` without a passing fit).
    WrongState = 11,
    /// The calibration fit failed a validity check (the reason code follows).
    FitRefused = 12,
    /// `store` failed: flash driver error, read-back mismatch or an implausible record.
    FlashError = 13,
    /// Too many wrong keys: wait before trying again.
    RateLimited = 14,
    /// `unlock` with a key that is not the device's; the device locks.
    WrongKey = 15,
    /// `unlock` on a board whose key was never provisioned (`key provision`, production).
    NoKey = 16,
    /// Online tracking owns the coefficients: a hand change would be undone within a second
    /// (`track off` first).
    Tracking = 17,
    /// A state-changing command without a CRC: not executed; echoed as parsed, `yes` executes
    /// it (`confirm`).
    Confirm = 18,
}

impl ErrorCode {
    /// Every code, in numeric order (for hosts that parse answers).
    pub const ALL: [ErrorCode; 18] = [
        Self::UnknownCommand,
        Self::Syntax,
        Self::BadNumber,
        Self::NotFinite,
        Self::OutOfRange,
        Self::BadChecksum,
        Self::LineTooLong,
        Self::InvalidCharacters,
        Self::Locked,
        Self::Busy,
        Self::WrongState,
        Self::FitRefused,
        Self::FlashError,
        Self::RateLimited,
        Self::WrongKey,
        Self::NoKey,
        Self::Tracking,
        Self::Confirm,
    ];

    /// The number after `ERR`.
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The short text after the code.
    pub const fn text(self) -> &'static str {
        match self {
            Self::UnknownCommand => "unknown command (try help)",
            Self::Syntax => "syntax error",
            Self::BadNumber => "not a number",
            Self::NotFinite => "number not finite",
            Self::OutOfRange => "value out of range",
            Self::BadChecksum => "bad checksum",
            Self::LineTooLong => "line too long",
            Self::InvalidCharacters => "invalid characters",
            Self::Locked => "locked (unlock first)",
            Self::Busy => "calibration in progress",
            Self::WrongState => "not possible now",
            Self::FitRefused => "fit refused",
            Self::FlashError => "flash error",
            Self::RateLimited => "too many attempts, wait",
            Self::WrongKey => "wrong key",
            Self::NoKey => "no key provisioned",
            Self::Tracking => "tracking on (track off first)",
            Self::Confirm => "confirm (send yes)",
        }
    }
}
