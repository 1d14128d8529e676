//! The set operations of the firmware's flag words (`CycleFlags`, `OutputStatus`): a newtype
//! over an unsigned integer whose named constants are single bits. One definition of the
//! operations for every such word, generated into the type by [`flag_set_ops!`].

/// Adds `empty`, `union`, `contains`, `intersects`, `without` and `is_empty` to a
/// `struct $name(pub $repr)` whose constants are bits.
macro_rules! flag_set_ops {
    ($name:ident) => {
        impl $name {
            /// No bit set.
            pub const fn empty() -> Self {
                Self(0)
            }
            /// The bits of both.
            pub const fn union(self, other: Self) -> Self {
                Self(self.0 | other.0)
            }
            /// Every bit of `other` is set.
            pub const fn contains(self, other: Self) -> bool {
                self.0 & other.0 == other.0
            }
            /// Any bit of `other` is set.
            pub const fn intersects(self, other: Self) -> bool {
                self.0 & other.0 != 0
            }
            /// With the bits of `other` cleared.
            pub const fn without(self, other: Self) -> Self {
                Self(self.0 & !other.0)
            }
            /// No bit is set.
            pub const fn is_empty(self) -> bool {
                self.0 == 0
            }
        }
    };
}
pub(crate) use flag_set_ops;
