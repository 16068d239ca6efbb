//! Enums and booleans as they travel in shared memory: as integer codes, converted with
//! `TryFrom` when read.
//!
//! A Rust enum or `bool` read from bytes another process wrote is undefined behaviour as soon as
//! the byte is not one of its values. The messages therefore carry a [`WireCode`] (a `u32`) or a
//! [`WireBool`] (a `u8`), which every bit pattern is, and every message type says with
//! [`WireCheck`] whether all of its codes are known. The transport checks each message as it
//! receives it; a bad one is counted and skipped, never read as a value.
//!
//! Inside a process the codes are always valid (they are made from the enums); [`WireCode::get`]
//! still reads a bad code as the type's conservative value ([`WireEnum::ON_BAD_CODE`]: no deck,
//! a missing compensation, a bad frame) rather than panicking.

use std::fmt;
use std::marker::PhantomData;

/// A field of a message whose code is not a value of its type.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{field}` holds {code}, which is no {kind}")]
pub struct BadWireValue {
    /// Where in the message (`state`, `context.vehicle.compensation`, `markers.markers[3].valid`).
    pub field: String,
    /// The type it should be (`DecisionState`, `bool`).
    pub kind: &'static str,
    pub code: u32,
}

impl BadWireValue {
    /// The same error seen from the struct that holds `parent`.
    pub fn within(self, parent: &str) -> Self {
        let field = if self.field.is_empty() {
            parent.to_string()
        } else if self.field.starts_with('[') {
            // An array's element: `markers[3].valid`.
            format!("{parent}{}", self.field)
        } else {
            format!("{parent}.{}", self.field)
        };
        Self { field, ..self }
    }
}

/// An enum that travels as a `u32` code (its discriminant).
pub trait WireEnum: Copy + 'static {
    /// The type's name in errors.
    const NAME: &'static str;
    /// How [`WireCode::get`] reads a code that is none of the values: the reading that never
    /// leads to a landing.
    const ON_BAD_CODE: Self;
    /// Every value, in code order (recordings write and read them by name).
    const VARIANTS: &'static [Self];
    fn code(self) -> u32;
    fn from_code(code: u32) -> Option<Self>;
    /// The variant's name as written in the source (`ClearToLand`).
    fn variant_name(self) -> &'static str;
}

/// Implements [`WireEnum`] and `TryFrom<u32>` for a fieldless enum with explicit discriminants;
/// the variant list must name every variant (checked by an exhaustive match).
///
/// With `Variant => "name"` in the list it also declares the names ([`crate::named_enum!`]):
/// one list for the codes, the names and `ALL`.
#[macro_export]
macro_rules! wire_enum {
    ($ty:ident, on_bad_code: $fallback:ident, [$($variant:ident => $name:literal),+ $(,)?]) => {
        $crate::wire_enum!($ty, on_bad_code: $fallback, [$($variant),+]);
        $crate::named_enum!($ty, [$($variant => $name),+]);
    };
    ($ty:ident, on_bad_code: $fallback:ident, [$($variant:ident),+ $(,)?]) => {
        impl $crate::wire::WireEnum for $ty {
            const NAME: &'static str = stringify!($ty);
            const ON_BAD_CODE: Self = Self::$fallback;
            const VARIANTS: &'static [Self] = &[$(Self::$variant),+];
            fn variant_name(self) -> &'static str {
                match self {
                    $(Self::$variant => stringify!($variant),)+
                }
            }
            fn code(self) -> u32 {
                // Every variant listed: a variant added to the enum and not here fails to compile.
                match self {
                    $(Self::$variant => Self::$variant as u32,)+
                }
            }
            fn from_code(code: u32) -> Option<Self> {
                $(if code == Self::$variant as u32 {
                    return Some(Self::$variant);
                })+
                None
            }
        }

        impl PartialEq<$crate::wire::WireCode<$ty>> for $ty {
            fn eq(&self, other: &$crate::wire::WireCode<$ty>) -> bool {
                other == self
            }
        }

        impl TryFrom<u32> for $ty {
            type Error = $crate::wire::BadWireValue;
            fn try_from(code: u32) -> Result<Self, $crate::wire::BadWireValue> {
                <Self as $crate::wire::WireEnum>::from_code(code).ok_or($crate::wire::BadWireValue {
                    field: String::new(),
                    kind: <Self as $crate::wire::WireEnum>::NAME,
                    code,
                })
            }
        }
    };
}

/// An enum value in a message: its code, any `u32` (so any bytes are a valid `WireCode`).
#[repr(transparent)]
pub struct WireCode<E> {
    code: u32,
    kind: PhantomData<E>,
}

impl<E> WireCode<E> {
    /// Any code, valid or not (what another process may have written; fault injection).
    pub const fn from_code(code: u32) -> Self {
        Self {
            code,
            kind: PhantomData,
        }
    }

    pub const fn code(self) -> u32 {
        self.code
    }
}

impl<E: WireEnum> WireCode<E> {
    pub fn new(value: E) -> Self {
        Self::from_code(value.code())
    }

    /// The value, or why the code is none.
    pub fn try_get(self) -> Result<E, BadWireValue> {
        E::from_code(self.code).ok_or(BadWireValue {
            field: String::new(),
            kind: E::NAME,
            code: self.code,
        })
    }

    /// The value; a bad code (which the transport never lets through) reads as
    /// [`WireEnum::ON_BAD_CODE`].
    pub fn get(self) -> E {
        E::from_code(self.code).unwrap_or(E::ON_BAD_CODE)
    }

    /// Whether the code is a value of `E`.
    pub fn check(self) -> Result<(), BadWireValue> {
        self.try_get().map(|_| ())
    }
}

impl<E> Clone for WireCode<E> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<E> Copy for WireCode<E> {}

impl<E> PartialEq for WireCode<E> {
    fn eq(&self, other: &Self) -> bool {
        self.code == other.code
    }
}
impl<E> Eq for WireCode<E> {}

impl<E: WireEnum> PartialEq<E> for WireCode<E> {
    fn eq(&self, other: &E) -> bool {
        self.code == other.code()
    }
}

impl<E: WireEnum> From<E> for WireCode<E> {
    fn from(value: E) -> Self {
        Self::new(value)
    }
}

impl<E: WireEnum + Default> Default for WireCode<E> {
    fn default() -> Self {
        Self::new(E::default())
    }
}

impl<E: WireEnum + fmt::Debug> fmt::Debug for WireCode<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match E::from_code(self.code) {
            Some(v) => v.fmt(f),
            None => write!(f, "<bad {} code {}>", E::NAME, self.code),
        }
    }
}

// SAFETY: a `u32` and a zero-sized marker: zero is a value.
unsafe impl<E> bytemuck::Zeroable for WireCode<E> {}
// SAFETY: as a `u32`, every bit pattern is a `WireCode` (whether it is a value of `E` is
// `check`'s question).
unsafe impl<E: 'static> bytemuck::AnyBitPattern for WireCode<E> {}

#[cfg(feature = "shm")]
// SAFETY: a `u32` and a zero-sized marker: plain data, the same layout in every process.
unsafe impl<E: WireEnum> iceoryx2::prelude::ZeroCopySend for WireCode<E> {
    unsafe fn type_name() -> &'static str {
        "deckwatch.WireCode.u32"
    }
}

/// A boolean in a message: 0 false, 1 true, any other byte a bad value (any byte is a valid
/// `WireBool`, unlike `bool`).
#[repr(transparent)]
#[derive(Clone, Copy, PartialEq, Eq, Default, bytemuck::AnyBitPattern)]
pub struct WireBool(u8);

#[cfg(feature = "shm")]
// SAFETY: one byte, plain data.
unsafe impl iceoryx2::prelude::ZeroCopySend for WireBool {
    unsafe fn type_name() -> &'static str {
        "deckwatch.WireBool.u8"
    }
}

impl WireBool {
    pub const FALSE: Self = Self(0);
    pub const TRUE: Self = Self(1);

    pub const fn new(value: bool) -> Self {
        Self(value as u8)
    }

    /// Any byte, valid or not (what another process may have written; fault injection).
    pub const fn from_byte(byte: u8) -> Self {
        Self(byte)
    }

    pub const fn byte(self) -> u8 {
        self.0
    }

    /// True only for 1: a bad byte (which the transport never lets through) reads as false.
    pub const fn get(self) -> bool {
        self.0 == 1
    }

    pub fn try_get(self) -> Result<bool, BadWireValue> {
        match self.0 {
            0 => Ok(false),
            1 => Ok(true),
            b => Err(BadWireValue {
                field: String::new(),
                kind: "bool",
                code: b as u32,
            }),
        }
    }

    pub fn check(self) -> Result<(), BadWireValue> {
        self.try_get().map(|_| ())
    }
}

impl From<bool> for WireBool {
    fn from(value: bool) -> Self {
        Self::new(value)
    }
}

impl PartialEq<bool> for WireBool {
    fn eq(&self, other: &bool) -> bool {
        self.0 == *other as u8
    }
}

impl fmt::Debug for WireBool {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            0 => f.write_str("false"),
            1 => f.write_str("true"),
            b => write!(f, "<bad bool byte {b}>"),
        }
    }
}

/// A message (or a part of one) whose every enum and boolean is a known value: what the
/// transport asks of each message before anyone reads it. Every field of a message is checked
/// (the impls come from one list of the messages' fields, `message_fields!`); numbers hold any
/// bytes.
pub trait WireCheck {
    /// Whether every value of the type passes (numbers): an array of them is not walked.
    const ANY_BYTES: bool = false;
    fn check_wire(&self) -> Result<(), BadWireValue>;
}

impl<E: WireEnum> WireCheck for WireCode<E> {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        self.check()
    }
}

impl WireCheck for WireBool {
    fn check_wire(&self) -> Result<(), BadWireValue> {
        self.check()
    }
}

/// Numbers: any bytes are one.
macro_rules! any_bytes {
    ($($ty:ty),+) => {$(
        impl WireCheck for $ty {
            const ANY_BYTES: bool = true;
            fn check_wire(&self) -> Result<(), BadWireValue> {
                Ok(())
            }
        }
    )+};
}
any_bytes!(u8, u16, u32, u64, usize, i32, i64, f32, f64);

impl<T: WireCheck, const N: usize> WireCheck for [T; N] {
    const ANY_BYTES: bool = T::ANY_BYTES;
    fn check_wire(&self) -> Result<(), BadWireValue> {
        if T::ANY_BYTES {
            return Ok(());
        }
        for (i, item) in self.iter().enumerate() {
            item.check_wire().map_err(|e| e.within(&format!("[{i}]")))?;
        }
        Ok(())
    }
}

/// [`WireCheck`] for a struct from the list of all its fields (`Type { a, b; added = value }`,
/// the form `message_fields!` hands out): it takes the struct apart, so a field left out of the
/// list does not compile; each field is checked in order, and the error names it.
#[macro_export]
macro_rules! wire_check_struct {
    ($ty:ident { $($field:ident),+ $(,)? $(; $($added:ident = $default:expr),+ $(,)?)? }) => {
        impl $crate::wire::WireCheck for $ty {
            fn check_wire(&self) -> Result<(), $crate::wire::BadWireValue> {
                let $ty { $($field,)+ $($($added,)+)? } = self;
                $($crate::wire::WireCheck::check_wire($field).map_err(|e| e.within(stringify!($field)))?;)+
                $($($crate::wire::WireCheck::check_wire($added).map_err(|e| e.within(stringify!($added)))?;)+)?
                Ok(())
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    enum Light {
        #[default]
        Red = 0,
        Green = 7,
    }
    wire_enum!(Light, on_bad_code: Red, [Red, Green]);

    #[test]
    fn codes_convert_both_ways_and_bad_ones_are_errors() {
        let w: WireCode<Light> = Light::Green.into();
        assert_eq!(w.code(), 7);
        assert_eq!(w, Light::Green);
        assert_eq!(w.try_get(), Ok(Light::Green));
        assert_eq!(Light::try_from(0), Ok(Light::Red));
        let bad = WireCode::<Light>::from_code(3);
        let e = bad.try_get().unwrap_err();
        assert_eq!((e.kind, e.code), ("Light", 3));
        assert_eq!(bad.get(), Light::Red);
        assert_eq!(format!("{bad:?}"), "<bad Light code 3>");
        assert_eq!(
            e.within("light").within("lamp").to_string(),
            "`lamp.light` holds 3, which is no Light"
        );
    }

    #[test]
    fn bools_are_zero_or_one() {
        assert!(WireBool::TRUE.get() && !WireBool::FALSE.get());
        assert_eq!(WireBool::from(true), true);
        let bad = WireBool::from_byte(2);
        assert!(!bad.get());
        assert_eq!(bad.try_get().unwrap_err().code, 2);
        assert_eq!(std::mem::size_of::<WireBool>(), 1);
        assert_eq!(std::mem::size_of::<WireCode<Light>>(), 4);
    }
}
