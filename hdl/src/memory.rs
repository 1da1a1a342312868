//! Memory arrays (register files and SRAMs) for register bundles.
//!
//! A [`Memory`] holds its words plus the read-data registers of its synchronous read ports, and
//! is accessed once per clock cycle through a [`MemCycle`] guard obtained from
//! [`Memory::cycle`]. The guard models real RTL port semantics:
//!
//! - **Latency 0** (a flip-flop register file): [`MemCycle::read`] returns the word combinationally.
//! - **Latency 1** (an SRAM): [`MemCycle::issue_read`] presents an address; the word appears in
//!   [`Memory::rdata`] in the next cycle and stays there until the port reads again.
//! - Writes ([`MemCycle::write`], [`MemCycle::write_lane`]) take effect at the clock edge, i.e.
//!   when the guard is dropped: reads in the same cycle see the old word (read-first).
//! - [`MemCycle::search`] is a parallel compare of every word (a CAM match line plus priority
//!   encoder); only flip-flop arrays declare search ports.
//!
//! Every access is counted against the declared ports and a debug assertion fires when a cycle
//! uses more ports than declared, so a block's `eval` cannot silently do more per cycle than its
//! description promises.

use crate::describe::MemDesc;

/// Port counts and read latency of a memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemPorts {
    /// Read ports (each does one read per cycle).
    pub read: u32,
    /// Write ports (each does one whole-word or one lane write per cycle).
    pub write: u32,
    /// Parallel search ports (CAM compare of all words), 0 for SRAMs.
    pub search: u32,
    /// Cycles from address to data: 0 (flip-flops) or 1 (synchronous SRAM).
    pub read_latency: u32,
}

/// A memory array of `depth` words of type `T` with declared ports (a fixed array sized at
/// reset, and one read-data register per read port).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Memory<T> {
    words: Box<[T]>,
    rdata: Box<[T]>,
    ports: MemPorts,
}

impl<T: Clone> Memory<T> {
    /// A memory of `depth` words, all `init` (the reset value; read-data registers too), with
    /// the given ports. Read latency must be 0 or 1.
    pub fn new(depth: usize, init: T, ports: MemPorts) -> Self {
        debug_assert!(ports.read_latency <= 1, "read latency must be 0 or 1");
        Memory {
            words: vec![init.clone(); depth].into_boxed_slice(),
            rdata: vec![init; ports.read as usize].into_boxed_slice(),
            ports,
        }
    }

    /// Makes this memory equal to `other` (words and read-data registers), reusing its storage
    /// where the depths match.
    pub fn copy_from(&mut self, other: &Memory<T>) {
        if self.words.len() == other.words.len() && self.rdata.len() == other.rdata.len() {
            self.words.clone_from_slice(&other.words);
            self.rdata.clone_from_slice(&other.rdata);
            self.ports = other.ports;
        } else {
            *self = other.clone();
        }
    }

    /// Number of words.
    pub fn depth(&self) -> usize {
        self.words.len()
    }

    /// Declared ports and latency.
    pub fn ports(&self) -> MemPorts {
        self.ports
    }

    /// All words, for testbench inspection (a hierarchical reference, not a hardware port).
    pub fn words(&self) -> &[T] {
        &self.words
    }

    /// Read data of a latency-1 read port: the word addressed by the read issued on that port
    /// in the previous cycle (held while the port is idle).
    pub fn rdata(&self, port: usize) -> &T {
        debug_assert_eq!(self.ports.read_latency, 1, "rdata is for latency-1 ports");
        &self.rdata[port]
    }

    /// Access the memory for one clock cycle; the guard applies the cycle's reads and writes
    /// when it is dropped (the clock edge).
    pub fn cycle(&mut self) -> MemCycle<'_, T> {
        MemCycle {
            mem: self,
            reads: 0,
            searches: 0,
            issued: Vec::new(),
            writes: Vec::new(),
            clear: None,
        }
    }

    /// The description of this memory for [`crate::BlockDesc::memories`]; the word width is the
    /// sum of the field widths.
    pub fn desc(&self, name: &str, fields: Vec<(String, u32)>, doc: &str) -> MemDesc {
        let search = if self.ports.search > 0 {
            format!(
                " Flip-flop array with {} parallel search port(s) (CAM compare of every word \
                 plus a lowest-index priority encoder).",
                self.ports.search
            )
        } else {
            String::new()
        };
        MemDesc {
            name: name.to_string(),
            banks: 1,
            depth: self.words.len() as u32,
            width: fields.iter().map(|f| f.1).sum(),
            read_ports: self.ports.read,
            write_ports: self.ports.write,
            read_latency: self.ports.read_latency,
            fields,
            doc: format!("{doc}{search}"),
        }
    }
}

/// One clock cycle's access to a [`Memory`]: counts port use and applies issued reads and
/// writes at the clock edge (on drop).
pub struct MemCycle<'a, T: Clone> {
    mem: &'a mut Memory<T>,
    reads: u32,
    searches: u32,
    issued: Vec<(usize, usize)>,
    writes: Vec<(usize, T)>,
    clear: Option<fn(&mut T)>,
}

impl<T: Clone> MemCycle<'_, T> {
    fn count_read(&mut self) {
        self.reads += 1;
        debug_assert!(
            self.reads <= self.mem.ports.read,
            "more than {} reads in one cycle",
            self.mem.ports.read
        );
    }

    fn count_write(&mut self) {
        debug_assert!(
            self.writes.len() < self.mem.ports.write as usize,
            "more than {} writes in one cycle",
            self.mem.ports.write
        );
    }

    /// Read data of a latency-1 read port as of the start of this cycle (see [`Memory::rdata`]).
    pub fn rdata(&self, port: usize) -> &T {
        self.mem.rdata(port)
    }

    /// Combinational read of a latency-0 memory (the word as of the start of the cycle).
    pub fn read(&mut self, addr: usize) -> T {
        debug_assert_eq!(
            self.mem.ports.read_latency, 0,
            "read() is for latency-0 memories"
        );
        self.count_read();
        self.mem.words[addr].clone()
    }

    /// Presents `addr` on latency-1 read `port`; the word appears in [`Memory::rdata`] next cycle.
    pub fn issue_read(&mut self, port: usize, addr: usize) {
        debug_assert_eq!(
            self.mem.ports.read_latency, 1,
            "issue_read() is for latency-1 memories"
        );
        debug_assert!(port < self.mem.ports.read as usize, "no read port {port}");
        debug_assert!(addr < self.mem.words.len(), "address {addr} out of range");
        self.count_read();
        self.issued.push((port, addr));
    }

    /// Parallel search: the lowest index whose word (as of the start of the cycle) satisfies
    /// `pred`, as a CAM match vector and priority encoder would give.
    pub fn search(&mut self, pred: impl Fn(&T) -> bool) -> Option<usize> {
        self.searches += 1;
        debug_assert!(
            self.searches <= self.mem.ports.search,
            "more than {} searches in one cycle",
            self.mem.ports.search
        );
        self.mem.words.iter().position(pred)
    }

    /// Clears a field of every word at the clock edge (`clear` applied to each word), as a
    /// flip-flop array's common synchronous clear does (the valid bits of a table emptied in one
    /// cycle); it uses no write port, and the cycle's writes land after it. Flip-flop arrays
    /// (latency 0) only: an SRAM has no such clear.
    pub fn clear_all(&mut self, clear: fn(&mut T)) {
        debug_assert_eq!(
            self.mem.ports.read_latency, 0,
            "clear_all() is for flip-flop arrays"
        );
        self.clear = Some(clear);
    }

    /// Writes a whole word at the clock edge.
    pub fn write(&mut self, addr: usize, value: T) {
        debug_assert!(addr < self.mem.words.len(), "address {addr} out of range");
        self.count_write();
        self.writes.push((addr, value));
    }
}

impl<E: Clone> MemCycle<'_, Box<[E]>> {
    /// Writes one lane of a word made of lanes (a write with a per-lane write enable), leaving
    /// the other lanes unchanged.
    pub fn write_lane(&mut self, addr: usize, lane: usize, value: E) {
        debug_assert!(addr < self.mem.words.len(), "address {addr} out of range");
        self.count_write();
        let mut word = self.mem.words[addr].clone();
        word[lane] = value;
        self.writes.push((addr, word));
    }
}

impl<T: Clone> Drop for MemCycle<'_, T> {
    fn drop(&mut self) {
        // Read-first: reads issued this cycle capture the words before this cycle's writes.
        for &(port, addr) in &self.issued {
            self.mem.rdata[port] = self.mem.words[addr].clone();
        }
        if let Some(clear) = self.clear.take() {
            self.mem.words.iter_mut().for_each(clear);
        }
        for (addr, value) in self.writes.drain(..) {
            self.mem.words[addr] = value;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SRAM: MemPorts = MemPorts {
        read: 1,
        write: 1,
        search: 0,
        read_latency: 1,
    };
    const FLOPS: MemPorts = MemPorts {
        read: 2,
        write: 1,
        search: 1,
        read_latency: 0,
    };

    #[test]
    fn sram_read_has_one_cycle_latency_and_is_read_first() {
        let mut m: Memory<u32> = Memory::new(4, 0, SRAM);
        {
            let mut c = m.cycle();
            c.write(2, 7);
        }
        {
            let mut c = m.cycle();
            c.issue_read(0, 2);
            c.write(2, 9);
        }
        assert_eq!(*m.rdata(0), 7, "read in the write cycle sees the old word");
        {
            let mut c = m.cycle();
            c.issue_read(0, 2);
        }
        assert_eq!(*m.rdata(0), 9);
        drop(m.cycle());
        assert_eq!(*m.rdata(0), 9, "idle port holds its data");
    }

    #[test]
    fn flops_read_combinationally_and_search() {
        let mut m: Memory<u32> = Memory::new(5, 0, FLOPS);
        {
            let mut c = m.cycle();
            c.write(3, 4);
            assert_eq!(c.read(3), 0, "write lands at the clock edge");
        }
        let mut c = m.cycle();
        assert_eq!(c.read(3), 4);
        assert_eq!(c.search(|&w| w == 4), Some(3));
    }

    #[test]
    fn lane_write_keeps_other_lanes() {
        let mut m: Memory<Box<[u16]>> = Memory::new(2, vec![0; 3].into(), SRAM);
        {
            let mut c = m.cycle();
            c.write(1, vec![1, 2, 3].into());
        }
        {
            let mut c = m.cycle();
            c.write_lane(1, 2, 30);
        }
        assert_eq!(&*m.words()[1], &[1, 2, 30]);
    }

    #[test]
    #[should_panic(expected = "more than 1 writes")]
    fn port_limit_is_checked() {
        let mut m: Memory<u32> = Memory::new(4, 0, SRAM);
        let mut c = m.cycle();
        c.write(0, 1);
        c.write(1, 1);
    }

    #[test]
    fn clear_all_lands_at_the_edge_before_the_writes() {
        let mut m: Memory<u32> = Memory::new(3, 5, FLOPS);
        {
            let mut c = m.cycle();
            c.clear_all(|w| *w &= 1);
            c.write(2, 8);
            assert_eq!(c.read(0), 5, "the clear lands at the clock edge");
        }
        assert_eq!(m.words(), &[1, 1, 8]);
    }

    #[test]
    fn desc_sums_field_widths() {
        let m: Memory<u32> = Memory::new(8, 0, SRAM);
        let d = m.desc("m", vec![("a".into(), 3), ("b".into(), 5)], "test");
        assert_eq!((d.depth, d.width, d.read_latency), (8, 8, 1));
    }
}
