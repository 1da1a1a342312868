//! Port bundles declared once: [`bundle!`](crate::bundle) turns one declaration of a bundle —
//! its Rust fields and the list of its ports (name, width, documentation, how its value is read
//! from the fields) — into the struct, its [`Signals`](crate::Signals) implementation (for
//! traces and co-simulation) and its port list (for `describe()`, and so for Verilog and area),
//! so the three cannot drift apart.
//!
//! ```
//! use vtq_hdl::bundle;
//!
//! /// Widths of a toy bundle's fields.
//! #[derive(Debug, Clone, Copy, PartialEq, Eq)]
//! pub struct ToyWidths {
//!     /// Bits of an address.
//!     pub address: u32,
//! }
//!
//! bundle! {
//!     /// A toy request port bundle.
//!     #[derive(Debug, Clone, PartialEq, Eq)]
//!     pub struct ToyIn (In, w: ToyWidths, this) {
//!         /// The address requested, if any.
//!         pub address: Option<u64>,
//!         /// Four per-lane enables.
//!         pub lanes: [bool; 4],
//!     }
//!     ports {
//!         /// a request is presented
//!         sig valid (1) = this.address.is_some() as u64;
//!         /// its address
//!         sig address (w.address) = this.address.unwrap_or(0);
//!         /// per lane: enabled (traced as `enable_<lane>`)
//!         lanes enable (1, 4) = |i: usize| this.lanes[i] as u64;
//!     }
//! }
//!
//! use vtq_hdl::Signals;
//! let w = ToyWidths { address: 16 };
//! let b = ToyIn { widths: w, address: Some(0x40), lanes: [true, false, false, true] };
//! let ports = ToyIn::ports(&w);
//! assert_eq!(ports.iter().map(|p| (p.name.as_str(), p.width)).collect::<Vec<_>>(),
//!            [("valid", 1), ("address", 16), ("enable", 4)]);
//! let names: Vec<String> = b.signals().into_iter().map(|s| s.name).collect();
//! assert_eq!(names, ["valid", "address", "enable_0", "enable_1", "enable_2", "enable_3"]);
//! ```
//!
//! Port kinds: `sig name (width)` is one signal of that width; `lanes name (width, count)` is a
//! packed port of `width x count` bits traced as `name_<i>` (`value` is a closure of the lane
//! index); `bulk name (width)` is described but not traced (bulk data such as whole ray records,
//! whose value needs no trace).

/// Declares a port bundle once: the struct (with a `widths` field of the given widths type),
/// `ports(&widths)` (the [`PortDesc`](crate::PortDesc) of each port, in order, with the given
/// direction) and its [`Signals`](crate::Signals). See the [module documentation](self).
#[macro_export]
macro_rules! bundle {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident ($dir:ident, $w:ident : $wty:ty, $this:ident) {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $fty:ty ),* $(,)?
        }
        ports {
            $(
                #[doc = $doc:literal]
                $kind:ident $sig:ident ($width:expr $(, $count:expr)?) $(= $value:expr)? ;
            )*
        }
    ) => {
        $(#[$meta])*
        $vis struct $name {
            /// Widths of the fields (constant; they let the bundle list its signals).
            pub widths: $wty,
            $( $(#[$fmeta])* $fvis $field: $fty, )*
        }

        impl $name {
            /// The bundle's ports in order, for a block description.
            #[allow(unused_variables)]
            pub fn ports($w: &$wty) -> Vec<$crate::describe::PortDesc> {
                vec![
                    $(
                        $crate::describe::port(
                            stringify!($sig),
                            $crate::describe::Dir::$dir,
                            ($width) $( * ($count) )?,
                            $doc.trim(),
                        ),
                    )*
                ]
            }
        }

        impl $crate::block::Signals for $name {
            #[allow(unused_variables, clippy::redundant_closure_call)]
            fn signals(&self) -> Vec<$crate::block::Signal> {
                let $w = &self.widths;
                let $this = self;
                let mut signals = Vec::new();
                $(
                    $crate::__bundle_signal!(
                        $kind, signals, $sig, $width, [$($count)?], [$($value)?]
                    );
                )*
                signals
            }
        }
    };
}

/// One port's signals for [`bundle!`] (an implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_signal {
    (sig, $v:ident, $sig:ident, $width:expr, [], [$value:expr]) => {
        $v.push($crate::block::Signal::new(stringify!($sig), $width, $value));
    };
    (lanes, $v:ident, $sig:ident, $width:expr, [$count:expr], [$value:expr]) => {{
        let value = $value;
        for i in 0..($count) as usize {
            $v.push($crate::block::Signal::new(
                format!("{}_{}", stringify!($sig), i),
                $width,
                value(i),
            ));
        }
    }};
    (bulk, $v:ident, $sig:ident, $width:expr, [], []) => {};
}
