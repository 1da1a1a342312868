//! A block's registers declared once: each row of a [`RegTable`] names a register (or a bank of
//! them), gives its width, entry count and documentation, and says how its value is read from
//! the block's register bundle. The block's description (`BlockDesc::registers`, from
//! [`RegTable::descs`]) and its trace signals (`Block::reg_signals`, from
//! [`RegTable::signals`]) both come from the one table, so they cannot drift apart.

use crate::block::Signal;
use crate::describe::{reg, RegDesc};

/// Reads entry `i` of a bank from the register bundle.
type EntryFn<'a, R, T> = Box<dyn Fn(&R, usize) -> T + 'a>;

/// How a row's value is traced.
enum Trace<'a, R> {
    /// One register, traced under its name.
    One(Box<dyn Fn(&R) -> u64 + 'a>),
    /// A bank of registers, entry `i` traced as `<name>_<i>`.
    Bank(EntryFn<'a, R, u64>),
    /// A bank of 1-bit registers traced packed 64 to a signal: entry `i` is bit `i % 64` of
    /// `<name>_<i / 64>`.
    Bits(EntryFn<'a, R, bool>),
    /// A bank of `rows x cols` registers, entry `(i, j)` traced as `<name>_<i>_<j>` (row-major
    /// in the bank: entry `i * cols + j`).
    Grid(u32, EntryFn<'a, R, u64>),
    /// Described, not traced (wide state a waveform cannot usefully show, such as whole ray
    /// records).
    Untraced,
}

/// One row: a register or bank and how it is traced.
struct Row<'a, R> {
    desc: RegDesc,
    trace: Trace<'a, R>,
}

/// The registers of a block whose register bundle is `R`, in description order.
pub struct RegTable<'a, R> {
    rows: Vec<Row<'a, R>>,
}

impl<R> Default for RegTable<'_, R> {
    fn default() -> Self {
        RegTable { rows: Vec::new() }
    }
}

impl<'a, R> RegTable<'a, R> {
    /// An empty table.
    pub fn new() -> Self {
        Self::default()
    }

    fn push(&mut self, name: &str, width: u32, count: u32, doc: &str, trace: Trace<'a, R>) {
        self.rows.push(Row {
            desc: reg(name, width, count, doc),
            trace,
        });
    }

    /// One register of `width` bits whose value is `value(regs)`.
    pub fn one(
        &mut self,
        name: &str,
        width: u32,
        doc: &str,
        value: impl Fn(&R) -> u64 + 'a,
    ) -> &mut Self {
        self.push(name, width, 1, doc, Trace::One(Box::new(value)));
        self
    }

    /// A bank of `count` registers of `width` bits, entry `i` being `value(regs, i)`.
    pub fn bank(
        &mut self,
        name: &str,
        width: u32,
        count: u32,
        doc: &str,
        value: impl Fn(&R, usize) -> u64 + 'a,
    ) -> &mut Self {
        self.push(name, width, count, doc, Trace::Bank(Box::new(value)));
        self
    }

    /// A bank of `rows x cols` registers of `width` bits (per slot, per lane), entry `(i, j)`
    /// being `value(regs, i, j)`.
    pub fn grid(
        &mut self,
        name: &str,
        width: u32,
        (rows, cols): (u32, u32),
        doc: &str,
        value: impl Fn(&R, usize, usize) -> u64 + 'a,
    ) -> &mut Self {
        let c = cols as usize;
        let value = move |r: &R, k: usize| value(r, k / c, k % c);
        self.push(
            name,
            width,
            rows * cols,
            doc,
            Trace::Grid(cols, Box::new(value)),
        );
        self
    }

    /// A bank of `count` 1-bit registers, traced packed into 64-bit words.
    pub fn bits(
        &mut self,
        name: &str,
        count: u32,
        doc: &str,
        value: impl Fn(&R, usize) -> bool + 'a,
    ) -> &mut Self {
        self.push(name, 1, count, doc, Trace::Bits(Box::new(value)));
        self
    }

    /// A bank of `count` registers of `width` bits that is described but not traced.
    pub fn untraced(&mut self, name: &str, width: u32, count: u32, doc: &str) -> &mut Self {
        self.push(name, width, count, doc, Trace::Untraced);
        self
    }

    /// The registers' descriptions, in table order.
    pub fn descs(&self) -> Vec<RegDesc> {
        self.rows.iter().map(|r| r.desc.clone()).collect()
    }

    /// The registers `regs` as trace signals, in table order.
    pub fn signals(&self, regs: &R) -> Vec<Signal> {
        let mut out = Vec::new();
        for row in &self.rows {
            let d = &row.desc;
            match &row.trace {
                Trace::One(value) => out.push(Signal::new(d.name.clone(), d.width, value(regs))),
                Trace::Bank(value) => out.extend(
                    (0..d.count as usize)
                        .map(|i| Signal::new(format!("{}_{i}", d.name), d.width, value(regs, i))),
                ),
                Trace::Bits(value) => {
                    let count = d.count as usize;
                    for (k, start) in (0..count).step_by(64).enumerate() {
                        let end = (start + 64).min(count);
                        let word = (start..end)
                            .filter(|&i| value(regs, i))
                            .fold(0u64, |acc, i| acc | 1 << (i - start));
                        let width = (end - start) as u32;
                        out.push(Signal::new(format!("{}_{k}", d.name), width, word));
                    }
                }
                Trace::Grid(cols, value) => {
                    let c = *cols as usize;
                    out.extend((0..d.count as usize).map(|k| {
                        let name = format!("{}_{}_{}", d.name, k / c, k % c);
                        Signal::new(name, d.width, value(regs, k))
                    }))
                }
                Trace::Untraced => {}
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Regs {
        state: u64,
        bank: [u64; 2],
        valid: Vec<bool>,
    }

    #[test]
    fn one_table_gives_the_descriptions_and_the_signals() {
        let mut t = RegTable::<Regs>::new();
        t.one("state", 3, "FSM", |r| r.state)
            .bank("bank", 8, 2, "two", |r, i| r.bank[i])
            .bits("valid", 70, "valid bits", |r, i| r.valid[i])
            .grid("lane", 2, (2, 3), "per slot, per lane", |_, i, j| {
                (10 * i + j) as u64
            })
            .untraced("wide", 128, 4, "not traced");
        let names: Vec<_> = t.descs().into_iter().map(|d| (d.name, d.count)).collect();
        assert_eq!(
            names,
            [
                ("state".to_string(), 1),
                ("bank".to_string(), 2),
                ("valid".to_string(), 70),
                ("lane".to_string(), 6),
                ("wide".to_string(), 4)
            ]
        );
        let mut valid = vec![false; 70];
        valid[0] = true;
        valid[65] = true;
        let regs = Regs {
            state: 5,
            bank: [7, 9],
            valid,
        };
        let signals: Vec<_> = t
            .signals(&regs)
            .into_iter()
            .map(|s| (s.name, s.width, s.value))
            .collect();
        assert_eq!(
            signals,
            [
                ("state".to_string(), 3, 5),
                ("bank_0".to_string(), 8, 7),
                ("bank_1".to_string(), 8, 9),
                ("valid_0".to_string(), 64, 1),
                ("valid_1".to_string(), 6, 2),
                ("lane_0_0".to_string(), 2, 0),
                ("lane_0_1".to_string(), 2, 1),
                ("lane_0_2".to_string(), 2, 2),
                ("lane_1_0".to_string(), 2, 10),
                ("lane_1_1".to_string(), 2, 11),
                ("lane_1_2".to_string(), 2, 12),
            ]
        );
    }
}
