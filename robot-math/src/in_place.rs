//! Building a big value in place, in the slot where it will live.
//!
//! On a 20 KiB board a value of a few kilobytes built by value (`Type { .. }` or `Type::new()`)
//! is built on the stack and then copied to its static cell; inlined into a task's poll
//! function, it stays in that function's frame for good. [`init_in_place!`] writes each field
//! straight into the slot instead, and stops the build when a field is left out.
//!
//! ```
//! use core::mem::MaybeUninit;
//! use robot_math::init_in_place;
//!
//! struct Buffer {
//!     bytes: [u8; 4],
//!     len: usize,
//! }
//! struct Link {
//!     name: u8,
//!     rx: Buffer,
//! }
//! impl Buffer {
//!     fn init(slot: &mut MaybeUninit<Buffer>) -> &mut Buffer {
//!         init_in_place!(slot, Buffer { bytes: [0; 4], len: 0 })
//!     }
//! }
//! let mut slot = MaybeUninit::uninit();
//! // `rx` is itself built in place, by `Buffer::init` on its own slot.
//! let link = init_in_place!(&mut slot, Link { name: 7 } in_place { rx: Buffer::init() });
//! assert_eq!((link.name, link.rx.len), (7, 0));
//! ```

/// `init_in_place!(slot, Type { field: value, .. })` writes every field of `Type` into `slot`
/// (a `&mut MaybeUninit<Type>`) and returns the `&mut Type`.
/// `init_in_place!(slot, Type { .. } in_place { field: Field::init(args..) })` builds those
/// fields in place too: `Field::init(&mut MaybeUninit<Field>, args..)` on the field's own slot.
///
/// Each field is named once (the compiler refuses a field twice), and an exhaustive pattern
/// over the same names refuses a field left out: so every field is written, and the slot is
/// initialised when the macro returns. Use it where `Type`'s fields are visible. A value that
/// needs `unsafe` must have its own `unsafe` block, as anywhere else.
///
/// A field left out does not compile:
///
/// ```compile_fail
/// use core::mem::MaybeUninit;
/// struct Pair {
///     a: u8,
///     b: u8,
/// }
/// let mut slot = MaybeUninit::<Pair>::uninit();
/// robot_math::init_in_place!(&mut slot, Pair { a: 1 });
/// ```
///
/// Nor does a value that needs `unsafe` without its own `unsafe` block:
///
/// ```compile_fail
/// use core::mem::MaybeUninit;
/// struct Pair {
///     a: u8,
///     b: u8,
/// }
/// let five = 5u8;
/// let p: *const u8 = &five;
/// let mut slot = MaybeUninit::<Pair>::uninit();
/// robot_math::init_in_place!(&mut slot, Pair { a: *p, b: 0 });
/// ```
#[macro_export]
macro_rules! init_in_place {
    ($slot:expr, $ty:ident { $($field:ident: $value:expr),* $(,)? }) => {
        $crate::init_in_place!($slot, $ty { $($field: $value),* } in_place {})
    };
    ($slot:expr, $ty:ident { $($field:ident: $value:expr),* $(,)? }
        in_place { $($pfield:ident: $($init:ident)::+ ($($arg:expr),* $(,)?)),* $(,)? }) => {{
        let slot: &mut ::core::mem::MaybeUninit<$ty> = $slot;
        // Never called: it does not compile unless the two lists name every field, once.
        let _every_field = |v: &$ty| {
            let $ty { $($field: _,)* $($pfield: _,)* } = v;
        };
        // Never called either: the values type-checked outside `unsafe`, so one that needs
        // `unsafe` must say so where it is written (they are written inside it below).
        let _values_are_safe = |v: &mut $ty| {
            $(v.$field = $value;)*
        };
        let p = slot.as_mut_ptr();
        // Each value is written straight into its field through a raw pointer into the slot
        // (no reference to the uninitialised whole is made). Written as the argument of the
        // write, not bound first: a binding is a copy on the stack, which is what this macro
        // is for avoiding (the master's relay: 760 B more). So the values are worked out
        // inside `unsafe` (and type-checked outside it above).
        $(
            // SAFETY: `p` points into `slot`, valid for writes; the field is written once.
            unsafe { ::core::ptr::addr_of_mut!((*p).$field).write($value) };
        )*
        $(
            // SAFETY: as above; a `MaybeUninit` of the field's type has its layout.
            let field = unsafe {
                &mut *(::core::ptr::addr_of_mut!((*p).$pfield) as *mut ::core::mem::MaybeUninit<_>)
            };
            $($init)::+(field $(, $arg)*);
        )*
        // SAFETY: every field has been written (the pattern above names them all).
        unsafe { slot.assume_init_mut() }
    }};
}
