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
//!         /// Two response ports' data, if any.
//!         pub data: [Option<u64>; 2],
//!     }
//!     ports {
//!         /// a request is presented
//!         sig valid (1) = this.address.is_some() as u64;
//!         /// its address
//!         sig address (w.address) = this.address.unwrap_or(0);
//!         /// per lane: enabled (traced as `enable_<lane>`)
//!         lanes enable (1, 4) = |i: usize| this.lanes[i] as u64;
//!         /// per lane: a separate tag port `tag_<lane>`
//!         each tag (3, 2) = |i: usize| i as u64;
//!         /// a wide word, described but not traced
//!         bulk blob (512);
//!         /// a record's fields, described but not traced (their words for co-simulation)
//!         bulks rec ([("a", 3, "field a"), ("b", 70, "field b")]) = |f: usize| vec![f as u64 + 1];
//!         group resp (k < 2) {
//!             /// the response port carries data
//!             sig valid (1) = this.data[k].is_some() as u64;
//!             /// its data
//!             sig data (8) = this.data[k].unwrap_or(0);
//!         }
//!     }
//! }
//!
//! use vtq_hdl::Signals;
//! let w = ToyWidths { address: 16 };
//! let b = ToyIn {
//!     widths: w,
//!     address: Some(0x40),
//!     lanes: [true, false, false, true],
//!     data: [None, Some(7)],
//! };
//! let ports = ToyIn::ports(&w);
//! assert_eq!(
//!     ports.iter().map(|p| (p.name.as_str(), p.width)).collect::<Vec<_>>(),
//!     [("valid", 1), ("address", 16), ("enable", 4), ("tag_0", 3), ("tag_1", 3), ("blob", 512),
//!      ("rec_a", 3), ("rec_b", 70), ("resp0_valid", 1), ("resp0_data", 8), ("resp1_valid", 1),
//!      ("resp1_data", 8)]
//! );
//! let names: Vec<String> = b.signals().into_iter().map(|s| s.name).collect();
//! assert_eq!(
//!     names,
//!     ["valid", "address", "enable_0", "enable_1", "enable_2", "enable_3", "tag_0", "tag_1",
//!      "resp0_valid", "resp0_data", "resp1_valid", "resp1_data"]
//! );
//! assert_eq!(b.signals()[11].value, 7);
//! let bulk: Vec<(String, u32, u64)> =
//!     b.bulk_signals().into_iter().map(|s| (s.name, s.width, s.value)).collect();
//! assert_eq!(
//!     bulk,
//!     [("rec_a_0".into(), 3, 1), ("rec_b_0".into(), 64, 2), ("rec_b_1".into(), 6, 0)]
//! );
//! ```
//!
//! Port kinds:
//! - `sig name (width) = value;` one port of that width, traced as one signal;
//! - `lanes name (width, count) = |i| value;` one packed port of `width x count` bits, traced as
//!   `name_<i>` per lane;
//! - `each name (width, count) = |i| value;` `count` ports `name_<i>` of `width` bits each;
//! - `bulk name (width);` a port that is described but not traced (bulk data such as whole ray
//!   records, whose value needs no trace);
//! - `bulks prefix (table) = |f| words;` a family of bulk ports `<prefix>_<field>` from a table
//!   of `(field, width, doc)` (one table for the fields of a record that enters and leaves a
//!   block by two families of ports; the row's own documentation names the family); not traced
//!   by [`Signals::signals`](crate::Signals::signals), but the value of field `f` (its 64-bit
//!   words, lowest first) is given to co-simulation by
//!   [`Signals::bulk_signals`](crate::Signals::bulk_signals) as `<prefix>_<field>_<k>`;
//! - `group prefix (k < count) { rows }` the rows (of the kinds above) once per `k` in
//!   `0..count`, named `<prefix><k>_<name>`, in the order `k` = 0 first; `k` is a `usize` the
//!   rows' values may use;
//! - `nest prefix (widths) = Bundle { field: value, ... };` another bundle's ports in place, in
//!   its order, named `<prefix>_<name>` (`nest (widths) = ...` without a prefix keeps their
//!   names), with this row's direction: `Bundle` (a struct declared with `bundle!`, in scope by
//!   that name) is listed with `Bundle::ports(&widths)` and traced (its signals and bulk signals
//!   renamed the same way) from `Bundle { widths, field: value, ... }`, built from this bundle's
//!   fields. The row's documentation, if any, is put before each nested port's own (a prefix
//!   such as `RT unit:`). So a child's rows that a composite block passes on (its errors, its
//!   statistics events) are declared once and nested in both, each parent giving the widths.
//!
//! ```
//! vtq_hdl::bundle! {
//!     /// A child's event ports.
//!     #[derive(Debug, Clone)]
//!     pub struct Events (Out, w: u32, this) {
//!         /// Hits this cycle.
//!         pub hits: u64,
//!     }
//!     ports {
//!         /// hits this cycle
//!         sig hits (*w) = this.hits;
//!         /// per lane: a flag
//!         lanes flag (1, 2) = |i: usize| (this.hits >> i) & 1;
//!         /// a record, described but not traced
//!         bulks rec ([("a", 70, "field a")]) = |_f: usize| vec![this.hits, 1];
//!     }
//! }
//! vtq_hdl::bundle! {
//!     /// A composite's outputs: its child's events twice (one set wider), and its own.
//!     #[derive(Debug, Clone)]
//!     pub struct Parent (Out, w: u32, this) {
//!         /// The child's events.
//!         pub child: u64,
//!     }
//!     ports {
//!         /// Child:
//!         nest child (*w + 1) = Events { hits: this.child };
//!         nest (*w) = Events { hits: 0 };
//!         /// my own
//!         sig busy (1) = 1;
//!     }
//! }
//! use vtq_hdl::Signals;
//! let ports = Parent::ports(&3);
//! assert_eq!(
//!     ports.iter().map(|p| (p.name.as_str(), p.width, p.doc.as_str())).collect::<Vec<_>>(),
//!     [("child_hits", 4, "Child: hits this cycle"), ("child_flag", 2, "Child: per lane: a flag"),
//!      ("child_rec_a", 70, "Child: field a"), ("hits", 3, "hits this cycle"),
//!      ("flag", 2, "per lane: a flag"), ("rec_a", 70, "field a"), ("busy", 1, "my own")]
//! );
//! let b = Parent { widths: 3, child: 2 };
//! let signals: Vec<(String, u32, u64)> =
//!     b.signals().into_iter().map(|s| (s.name, s.width, s.value)).collect();
//! assert_eq!(
//!     signals,
//!     [("child_hits".into(), 4, 2), ("child_flag_0".into(), 1, 0), ("child_flag_1".into(), 1, 1),
//!      ("hits".into(), 3, 0), ("flag_0".into(), 1, 0), ("flag_1".into(), 1, 0),
//!      ("busy".into(), 1, 1)]
//! );
//! let bulk: Vec<String> = b.bulk_signals().into_iter().map(|s| s.name).collect();
//! assert_eq!(bulk, ["child_rec_a_0", "child_rec_a_1", "rec_a_0", "rec_a_1"]);
//! ```
//!
//! A block whose description interleaves input and output ports (the RT unit's, which groups a
//! request's ports with their answer) declares both bundles in one `bundle!` with two structs,
//! the first `In` and the second `Out`, and marks each row (or group) `In` or `Out`:
//!
//! ```
//! vtq_hdl::bundle! {
//!     /// Requests.
//!     #[derive(Debug, Clone)]
//!     pub struct ReqIn (In, w: u32, this) {
//!         /// The request.
//!         pub req: Option<u64>,
//!     }
//!     /// Answers.
//!     #[derive(Debug, Clone)]
//!     pub struct ReqOut (Out, w: u32, this) {
//!         /// A request is taken.
//!         pub ready: bool,
//!     }
//!     ports {
//!         /// a request is presented
//!         In sig req_valid (1) = this.req.is_some() as u64;
//!         /// it is taken
//!         Out sig req_ready (1) = this.ready as u64;
//!         /// its address
//!         In sig req_address (*w) = this.req.unwrap_or(0);
//!     }
//! }
//! let names = |p: Vec<vtq_hdl::PortDesc>| p.into_iter().map(|p| p.name).collect::<Vec<_>>();
//! assert_eq!(names(ReqIn::block_ports(&8)), ["req_valid", "req_ready", "req_address"]);
//! assert_eq!(names(ReqIn::ports(&8)), ["req_valid", "req_address"]);
//! assert_eq!(names(ReqOut::ports(&8)), ["req_ready"]);
//! ```
//!
//! A port's documentation is its doc comment (lines joined with spaces).

use crate::describe::{Dir, PortDesc};

/// Declares a port bundle once: the struct (with a `widths` field of the given widths type),
/// `ports(&widths)` (the [`PortDesc`](crate::PortDesc) of each port, in order, with the given
/// direction) and its [`Signals`](crate::Signals); or, with two structs (inputs, then outputs),
/// both bundles and `block_ports(&widths)` on the first (every port in declaration order). See
/// the [module documentation](self).
#[macro_export]
macro_rules! bundle {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident ($dir:ident, $w:ident : $wty:ty, $this:ident) {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $fty:ty ),* $(,)?
        }
        ports { $($rows:tt)* }
    ) => {
        $crate::__bundle_rows! {
            @munch {
                { $(#[$meta])* $vis struct $name ($dir, $w : $wty, $this) {
                    $( $(#[$fmeta])* $fvis $field : $fty, )*
                } }
            } (fixed $dir (stringify) one) [] $($rows)*
        }
    };
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident (In, $w:ident : $wty:ty, $this:ident) {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $fty:ty ),* $(,)?
        }
        $(#[$ometa:meta])*
        $ovis:vis struct $oname:ident (Out, $ow:ident : $owty:ty, $othis:ident) {
            $( $(#[$ofmeta:meta])* $ofvis:vis $ofield:ident : $ofty:ty ),* $(,)?
        }
        ports { $($rows:tt)* }
    ) => {
        $crate::__bundle_rows! {
            @munch {
                { $(#[$meta])* $vis struct $name (In, $w : $wty, $this) {
                    $( $(#[$fmeta])* $fvis $field : $fty, )*
                } }
                { $(#[$ometa])* $ovis struct $oname (Out, $ow : $owty, $othis) {
                    $( $(#[$ofmeta])* $ofvis $ofield : $ofty, )*
                } }
            } (free) [] $($rows)*
        }
    };
}

/// Normalizes [`bundle!`]'s port rows to `[dir kind (name) (width) ...]`, one row per
/// expansion step (an implementation detail of the macro). The mode says where a row's
/// direction and name come from: `(fixed dir namer state)` (the bundle's direction, or a
/// group's; `state` is `one`, or the group's way back to the bundle's rows) or `(free)` (each
/// row names its direction: two bundles).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_rows {
    // All rows read: emit the bundles.
    (@munch $ctx:tt (fixed $d:ident $nm:tt one) [$($acc:tt)*]) => {
        $crate::__bundle_impl! { $ctx [$($acc)*] }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*]) => {
        $crate::__bundle_impl! { $ctx [$($acc)*] }
    };
    // A group's rows read: the group joins the bundle's rows.
    (@munch $ctx:tt (fixed $gd:ident $nm:tt
        (in_group $mode:tt [$($acc:tt)*] { $($rest:tt)* } $k:ident ($n:expr))) [$($inner:tt)*]) => {
        $crate::__bundle_rows! {
            @munch $ctx $mode [$($acc)* [$gd group $k ($n) [$($inner)*]]] $($rest)*
        }
    };
    // A group of rows repeated per index (no documentation of its own).
    (@munch $ctx:tt (fixed $d:ident $nm:tt one) [$($acc:tt)*]
        group $prefix:ident ($k:ident < $n:expr) { $($inner:tt)* } $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx
            (fixed $d (group $prefix $k)
                (in_group (fixed $d $nm one) [$($acc)*] { $($rest)* } $k ($n)))
            [] $($inner)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*]
        $rd:ident group $prefix:ident ($k:ident < $n:expr) { $($inner:tt)* } $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx
            (fixed $rd (group $prefix $k) (in_group (free) [$($acc)*] { $($rest)* } $k ($n)))
            [] $($inner)*
        }
    };
    // One row of each kind, with the bundle's (or group's) direction.
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])+
        sig $name:ident ($width:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d sig ($crate::__bundle_name!($nm $name))
                ($width) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])+
        lanes $name:ident ($width:expr, $count:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d lanes ($crate::__bundle_name!($nm $name))
                ($width) ($count) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])+
        each $name:ident ($width:expr, $count:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d each ($crate::__bundle_name!($nm $name))
                ($width) ($count) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])+
        bulk $name:ident ($width:expr) ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d bulk ($crate::__bundle_name!($nm $name))
                ($width) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])+
        bulks $name:ident ($table:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d bulks ($crate::__bundle_name!($nm $name))
                ($table) ($value)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])*
        nest $prefix:ident ($widths:expr) = $ty:ident { $($field:ident : $value:expr),* $(,)? } ;
        $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d nest ($crate::__bundle_name!($nm $prefix))
                ($ty) ($widths) ($($field ($value))*) ($($doc),*)]] $($rest)*
        }
    };
    (@munch $ctx:tt (fixed $d:ident $nm:tt $st:tt) [$($acc:tt)*] $(#[doc = $doc:tt])*
        nest ($widths:expr) = $ty:ident { $($field:ident : $value:expr),* $(,)? } ;
        $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (fixed $d $nm $st) [$($acc)* [$d nest ($crate::__bundle_name!($nm))
                ($ty) ($widths) ($($field ($value))*) ($($doc),*)]] $($rest)*
        }
    };
    // One row of each kind, naming its own direction.
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])+
        $rd:ident sig $name:ident ($width:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd sig ($crate::__bundle_name!((stringify) $name))
                ($width) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])+
        $rd:ident lanes $name:ident ($width:expr, $count:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd lanes ($crate::__bundle_name!((stringify) $name))
                ($width) ($count) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])+
        $rd:ident each $name:ident ($width:expr, $count:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd each ($crate::__bundle_name!((stringify) $name))
                ($width) ($count) ($value) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])+
        $rd:ident bulk $name:ident ($width:expr) ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd bulk ($crate::__bundle_name!((stringify) $name))
                ($width) ($($doc),+)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])+
        $rd:ident bulks $name:ident ($table:expr) = $value:expr ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd bulks ($crate::__bundle_name!((stringify) $name))
                ($table) ($value)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])*
        $rd:ident nest $prefix:ident ($widths:expr)
        = $ty:ident { $($field:ident : $value:expr),* $(,)? } ; $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd nest ($crate::__bundle_name!((stringify) $prefix))
                ($ty) ($widths) ($($field ($value))*) ($($doc),*)]] $($rest)*
        }
    };
    (@munch $ctx:tt (free) [$($acc:tt)*] $(#[doc = $doc:tt])*
        $rd:ident nest ($widths:expr) = $ty:ident { $($field:ident : $value:expr),* $(,)? } ;
        $($rest:tt)*) => {
        $crate::__bundle_rows! {
            @munch $ctx (free) [$($acc)* [$rd nest ($crate::__bundle_name!((stringify)))
                ($ty) ($widths) ($($field ($value))*) ($($doc),*)]] $($rest)*
        }
    };
}

/// The name of a [`bundle!`] port: the row's identifier, or in a group
/// `<prefix><k>_<identifier>`; without an identifier (a `nest` row without a prefix), the
/// empty name, or in a group `<prefix><k>` (an implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_name {
    ((stringify) $name:ident) => {
        ::std::string::String::from(stringify!($name))
    };
    ((group $prefix:ident $k:ident) $name:ident) => {
        format!("{}{}_{}", stringify!($prefix), $k, stringify!($name))
    };
    ((stringify)) => {
        ::std::string::String::new()
    };
    ((group $prefix:ident $k:ident)) => {
        format!("{}{}", stringify!($prefix), $k)
    };
}

/// Emits [`bundle!`]'s structs, port lists and [`Signals`](crate::Signals) from the normalized
/// rows (an implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_impl {
    ({ $one:tt } [$($row:tt)*]) => {
        $crate::__bundle_impl! { @struct $one [$($row)*] }
    };
    ({ $inputs:tt $outputs:tt } [$($row:tt)*]) => {
        $crate::__bundle_impl! { @struct $inputs [$($row)*] }
        $crate::__bundle_impl! { @struct $outputs [$($row)*] }
        $crate::__bundle_impl! { @block $inputs [$($row)*] }
    };
    (@struct {
        $(#[$meta:meta])*
        $vis:vis struct $name:ident ($dir:ident, $w:ident : $wty:ty, $this:ident) {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $fty:ty, )*
        }
    } [$($row:tt)*]) => {
        $(#[$meta])*
        $vis struct $name {
            /// Widths of the fields (constant; they let the bundle list its signals).
            pub widths: $wty,
            $( $(#[$fmeta])* $fvis $field: $fty, )*
        }

        impl $name {
            /// The bundle's ports in order, for a block description.
            #[allow(unused_variables, unused_mut, clippy::vec_init_then_push)]
            pub fn ports($w: &$wty) -> Vec<$crate::describe::PortDesc> {
                let mut ports = Vec::new();
                $( $crate::__bundle_port!(ports, Some($crate::describe::Dir::$dir), $row); )*
                ports
            }
        }

        impl $crate::block::Signals for $name {
            #[allow(
                unused_variables,
                unused_mut,
                clippy::redundant_closure_call,
                clippy::vec_init_then_push
            )]
            fn signals(&self) -> Vec<$crate::block::Signal> {
                let $w = &self.widths;
                let $this = self;
                let mut signals = Vec::new();
                $( $crate::__bundle_signal!($dir, signals, $row); )*
                signals
            }

            #[allow(
                unused_variables,
                unused_mut,
                clippy::redundant_closure_call,
                clippy::vec_init_then_push
            )]
            fn bulk_signals(&self) -> Vec<$crate::block::Signal> {
                let $w = &self.widths;
                let $this = self;
                let mut signals = Vec::new();
                $( $crate::__bundle_bulk_signal!($dir, signals, $row); )*
                signals
            }
        }
    };
    (@block {
        $(#[$meta:meta])*
        $vis:vis struct $name:ident (In, $w:ident : $wty:ty, $this:ident) { $($fields:tt)* }
    } [$($row:tt)*]) => {
        impl $name {
            /// Every port of the block these inputs belong to, inputs and outputs in declaration
            /// order, for its description.
            #[allow(unused_variables, clippy::vec_init_then_push)]
            pub fn block_ports($w: &$wty) -> Vec<$crate::describe::PortDesc> {
                let mut ports = Vec::new();
                $( $crate::__bundle_port!(ports, None, $row); )*
                ports
            }
        }
    };
}

/// One normalized row's port descriptions for [`bundle!`], if its direction is wanted (an
/// implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_port {
    ($v:ident, $want:expr, [$rd:ident $($row:tt)*]) => {
        if $crate::bundle::wanted($want, $crate::describe::Dir::$rd) {
            $crate::__bundle_port!(@row $v, $rd, [$($row)*]);
        }
    };
    (@row $v:ident, $rd:ident, [sig ($name:expr) ($width:expr) ($value:expr) ($($doc:tt),+)]) => {
        $v.push($crate::bundle::port_desc(&$name, $crate::describe::Dir::$rd, $width, &[$($doc),+]));
    };
    (@row $v:ident, $rd:ident,
        [lanes ($name:expr) ($width:expr) ($count:expr) ($value:expr) ($($doc:tt),+)]) => {
        $v.push($crate::bundle::port_desc(
            &$name,
            $crate::describe::Dir::$rd,
            ($width) * ($count),
            &[$($doc),+],
        ));
    };
    (@row $v:ident, $rd:ident,
        [each ($name:expr) ($width:expr) ($count:expr) ($value:expr) ($($doc:tt),+)]) => {
        for i in 0..($count) as usize {
            $v.push($crate::bundle::port_desc(
                &format!("{}_{}", $name, i),
                $crate::describe::Dir::$rd,
                $width,
                &[$($doc),+],
            ));
        }
    };
    (@row $v:ident, $rd:ident, [bulk ($name:expr) ($width:expr) ($($doc:tt),+)]) => {
        $v.push($crate::bundle::port_desc(&$name, $crate::describe::Dir::$rd, $width, &[$($doc),+]));
    };
    (@row $v:ident, $rd:ident, [bulks ($name:expr) ($table:expr) ($value:expr)]) => {
        let prefix = $name;
        for (field, width, doc) in $table {
            $v.push($crate::bundle::port_desc(
                &format!("{}_{}", prefix, field),
                $crate::describe::Dir::$rd,
                width,
                &[doc],
            ));
        }
    };
    (@row $v:ident, $rd:ident, [nest ($prefix:expr) ($ty:ident) ($widths:expr)
        ($($field:ident ($value:expr))*) ($($doc:tt),*)]) => {
        $crate::bundle::push_nested_ports(
            &mut $v,
            $prefix,
            $crate::describe::Dir::$rd,
            &[$($doc),*],
            $ty::ports(&$widths),
        );
    };
    (@row $v:ident, $rd:ident, [group $k:ident ($n:expr) [$([$ird:ident $($inner:tt)*])*]]) => {
        for $k in 0..($n) as usize {
            $( $crate::__bundle_port!(@row $v, $ird, [$($inner)*]); )*
        }
    };
}

/// One normalized row's signals for [`bundle!`], if it belongs to the bundle of direction
/// `$want` (an implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_signal {
    (In, $v:ident, [In $($row:tt)*]) => {
        $crate::__bundle_signal!(@row $v, [$($row)*]);
    };
    (Out, $v:ident, [Out $($row:tt)*]) => {
        $crate::__bundle_signal!(@row $v, [$($row)*]);
    };
    (In, $v:ident, [Out $($row:tt)*]) => {};
    (Out, $v:ident, [In $($row:tt)*]) => {};
    (@row $v:ident, [sig ($name:expr) ($width:expr) ($value:expr) ($($doc:tt),+)]) => {
        $v.push($crate::block::Signal::new($name, $width, $value));
    };
    (@row $v:ident, [lanes ($name:expr) ($width:expr) ($count:expr) ($value:expr) ($($doc:tt),+)]) => {
        $crate::__bundle_signal!(@lanes $v, ($name) ($width) ($count) ($value));
    };
    (@row $v:ident, [each ($name:expr) ($width:expr) ($count:expr) ($value:expr) ($($doc:tt),+)]) => {
        $crate::__bundle_signal!(@lanes $v, ($name) ($width) ($count) ($value));
    };
    (@row $v:ident, [bulk ($name:expr) ($width:expr) ($($doc:tt),+)]) => {};
    (@row $v:ident, [bulks ($name:expr) ($table:expr) ($value:expr)]) => {};
    (@row $v:ident, [nest ($prefix:expr) ($ty:ident) ($widths:expr)
        ($($field:ident ($value:expr))*) ($($doc:tt),*)]) => {
        $crate::__bundle_nested!($v, signals, ($prefix) ($ty) ($widths) ($($field ($value))*));
    };
    (@row $v:ident, [group $k:ident ($n:expr) [$([$ird:ident $($inner:tt)*])*]]) => {
        for $k in 0..($n) as usize {
            $( $crate::__bundle_signal!(@row $v, [$($inner)*]); )*
        }
    };
    (@lanes $v:ident, ($name:expr) ($width:expr) ($count:expr) ($value:expr)) => {{
        let name = $name;
        let value = $value;
        for i in 0..($count) as usize {
            $v.push($crate::block::Signal::new(format!("{}_{}", name, i), $width, value(i)));
        }
    }};
}

/// One normalized row's bulk signals for [`bundle!`] (the 64-bit words of its `bulks` ports),
/// if it belongs to the bundle of direction `$want` (an implementation detail of the macro).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_bulk_signal {
    (In, $v:ident, [In $($row:tt)*]) => {
        $crate::__bundle_bulk_signal!(@row $v, [$($row)*]);
    };
    (Out, $v:ident, [Out $($row:tt)*]) => {
        $crate::__bundle_bulk_signal!(@row $v, [$($row)*]);
    };
    (In, $v:ident, [Out $($row:tt)*]) => {};
    (Out, $v:ident, [In $($row:tt)*]) => {};
    (@row $v:ident, [bulks ($name:expr) ($table:expr) ($value:expr)]) => {{
        let prefix = $name;
        let value = $value;
        for (f, (field, width, _)) in $table.into_iter().enumerate() {
            $crate::bundle::push_words(&mut $v, &format!("{}_{}", prefix, field), width, value(f));
        }
    }};
    (@row $v:ident, [nest ($prefix:expr) ($ty:ident) ($widths:expr)
        ($($field:ident ($value:expr))*) ($($doc:tt),*)]) => {
        $crate::__bundle_nested!($v, bulk_signals, ($prefix) ($ty) ($widths) ($($field ($value))*));
    };
    (@row $v:ident, [group $k:ident ($n:expr) [$([$ird:ident $($inner:tt)*])*]]) => {
        for $k in 0..($n) as usize {
            $( $crate::__bundle_bulk_signal!(@row $v, [$($inner)*]); )*
        }
    };
    (@row $v:ident, [$($other:tt)*]) => {};
}

/// A `nest` row's signals (`$method`: `signals` or `bulk_signals` of the nested bundle built
/// from its fields), renamed with its prefix (an implementation detail of [`bundle!`]).
#[doc(hidden)]
#[macro_export]
macro_rules! __bundle_nested {
    ($v:ident, $method:ident, ($prefix:expr) ($ty:ident) ($widths:expr)
        ($($field:ident ($value:expr))*)) => {{
        let nested = $ty { widths: $widths, $($field: $value),* };
        $crate::bundle::push_nested_signals(
            &mut $v,
            $prefix,
            $crate::block::Signals::$method(&nested),
        );
    }};
}

/// Appends the signals of a `width`-bit bulk port `name` whose value is `words` (64-bit words,
/// the lowest first; missing words are zero): `<name>_<k>` for word `k`, 64 bits each but the
/// last (an implementation detail of [`bundle!`]).
#[doc(hidden)]
pub fn push_words(
    signals: &mut Vec<crate::block::Signal>,
    name: &str,
    width: u32,
    words: Vec<u64>,
) {
    for k in 0..width.div_ceil(64) {
        let bits = (width - 64 * k).min(64);
        let word = words.get(k as usize).copied().unwrap_or(0);
        debug_assert!(
            bits == 64 || word >> bits == 0,
            "bulk port {name}: word {k} does not fit its {bits} bits"
        );
        signals.push(crate::block::Signal::new(format!("{name}_{k}"), bits, word));
    }
}

/// The name of a nested bundle's port or signal `name` under `prefix`: `<prefix>_<name>`, or
/// `name` for the empty prefix.
fn nested_name(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_string()
    } else {
        format!("{prefix}_{name}")
    }
}

/// Appends a nested bundle's ports `nested` to `ports` (a `nest` row of [`bundle!`]): each
/// renamed under `prefix`, with the direction `dir` of the row and its documentation lines
/// `doc` (if any) before the port's own (an implementation detail of the macro).
#[doc(hidden)]
pub fn push_nested_ports(
    ports: &mut Vec<PortDesc>,
    prefix: String,
    dir: Dir,
    doc: &[&str],
    nested: Vec<PortDesc>,
) {
    for p in nested {
        let mut lines: Vec<&str> = doc.to_vec();
        lines.push(&p.doc);
        ports.push(port_desc(
            &nested_name(&prefix, &p.name),
            dir,
            p.width,
            &lines,
        ));
    }
}

/// Appends a nested bundle's signals `nested` to `signals`, each renamed under `prefix` (a
/// `nest` row of [`bundle!`]; an implementation detail of the macro).
#[doc(hidden)]
pub fn push_nested_signals(
    signals: &mut Vec<crate::block::Signal>,
    prefix: String,
    nested: Vec<crate::block::Signal>,
) {
    signals.extend(nested.into_iter().map(|s| crate::block::Signal {
        name: nested_name(&prefix, &s.name),
        ..s
    }));
}

/// Whether a port of direction `dir` is wanted by a port list of direction `want` (`None`: all).
#[doc(hidden)]
pub fn wanted(want: Option<Dir>, dir: Dir) -> bool {
    want.is_none_or(|w| w == dir)
}

/// A port description with the documentation lines `doc` joined by spaces.
#[doc(hidden)]
pub fn port_desc(name: &str, dir: Dir, width: u32, doc: &[&str]) -> PortDesc {
    let doc: Vec<&str> = doc.iter().map(|d| d.trim()).collect();
    crate::describe::port(name, dir, width, &doc.join(" "))
}
