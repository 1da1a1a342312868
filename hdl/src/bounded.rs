//! Register arrays whose depth is a declared hardware parameter: [`BoundedVec`] (an ordered list
//! of at most `capacity` entries) and [`BoundedDeque`] (a FIFO of at most `capacity` entries).
//! A register bundle holds these instead of growable collections, so its storage is the
//! declared depth x the entry width whatever happens; a push beyond the depth is refused (the
//! block raises its error or the caller's protocol forbids it). Two arrays are equal when they
//! hold the same entries (whatever their depths).

use std::collections::VecDeque;
use std::ops::Deref;

/// A push was refused: the array is at its declared depth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("register array full ({capacity} entries)")]
pub struct Full {
    /// The declared depth.
    pub capacity: usize,
}

/// An ordered register list of at most `capacity` entries (the default is an empty list of
/// depth 0).
#[derive(Debug, Clone, Default)]
pub struct BoundedVec<T> {
    items: Vec<T>,
    capacity: usize,
}

impl<T: PartialEq> PartialEq for BoundedVec<T> {
    fn eq(&self, other: &Self) -> bool {
        self.items == other.items
    }
}

impl<T: Eq> Eq for BoundedVec<T> {}

impl<T> BoundedVec<T> {
    /// An empty list of depth `capacity`.
    pub fn new(capacity: usize) -> Self {
        BoundedVec {
            items: Vec::with_capacity(capacity),
            capacity,
        }
    }

    /// A list of depth `capacity` holding `items`, or `Full` if they do not fit.
    pub fn with(capacity: usize, items: impl IntoIterator<Item = T>) -> Result<Self, Full> {
        let mut v = BoundedVec::new(capacity);
        for item in items {
            v.push(item)?;
        }
        Ok(v)
    }

    /// The declared depth.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// The entries as a plain vector.
    pub fn into_vec(self) -> Vec<T> {
        self.items
    }

    /// The entries, writable.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.items
    }

    /// Appends `item`, or refuses it at the declared depth.
    pub fn push(&mut self, item: T) -> Result<(), Full> {
        if self.items.len() >= self.capacity {
            return Err(Full {
                capacity: self.capacity,
            });
        }
        self.items.push(item);
        Ok(())
    }

    /// Removes and returns the entry at `index` (later entries move up).
    pub fn remove(&mut self, index: usize) -> T {
        self.items.remove(index)
    }

    /// Removes and returns the last entry.
    pub fn pop(&mut self) -> Option<T> {
        self.items.pop()
    }

    /// Removes and returns the first `n` entries (at most all of them; later entries move up).
    pub fn take_front(&mut self, n: usize) -> Vec<T> {
        self.items.drain(..n.min(self.items.len())).collect()
    }

    /// Removes every entry.
    pub fn clear(&mut self) {
        self.items.clear()
    }
}

impl<T: Clone> BoundedVec<T> {
    /// The same entries in a list of depth `capacity`, or `Full` if they do not fit.
    pub fn with_capacity_of(&self, capacity: usize) -> Result<Self, Full> {
        BoundedVec::with(capacity, self.items.iter().cloned())
    }
}

impl<'a, T> IntoIterator for &'a BoundedVec<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;

    fn into_iter(self) -> Self::IntoIter {
        self.items.iter()
    }
}

impl<T> Deref for BoundedVec<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        &self.items
    }
}

/// A register FIFO of at most `capacity` entries.
#[derive(Debug, Clone, Default)]
pub struct BoundedDeque<T> {
    items: VecDeque<T>,
    capacity: usize,
}

impl<T: PartialEq> PartialEq for BoundedDeque<T> {
    fn eq(&self, other: &Self) -> bool {
        self.items == other.items
    }
}

impl<T: Eq> Eq for BoundedDeque<T> {}

impl<T> BoundedDeque<T> {
    /// An empty FIFO of depth `capacity`.
    pub fn new(capacity: usize) -> Self {
        BoundedDeque {
            items: VecDeque::with_capacity(capacity),
            capacity,
        }
    }

    /// The declared depth.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether the FIFO is empty.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Appends `item` at the tail, or refuses it at the declared depth.
    pub fn push_back(&mut self, item: T) -> Result<(), Full> {
        if self.items.len() >= self.capacity {
            return Err(Full {
                capacity: self.capacity,
            });
        }
        self.items.push_back(item);
        Ok(())
    }

    /// Removes and returns the head.
    pub fn pop_front(&mut self) -> Option<T> {
        self.items.pop_front()
    }

    /// The head.
    pub fn front(&self) -> Option<&T> {
        self.items.front()
    }

    /// The entries, head first.
    pub fn iter(&self) -> impl Iterator<Item = &T> {
        self.items.iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pushes_beyond_the_depth_are_refused() {
        let mut v = BoundedVec::new(2);
        assert_eq!((v.push(1), v.push(2)), (Ok(()), Ok(())));
        assert_eq!(v.push(3), Err(Full { capacity: 2 }));
        assert_eq!(&*v, &[1, 2]);
        assert_eq!(v.remove(0), 1);
        v.push(4).unwrap();
        assert_eq!((v.take_front(1), &*v), (vec![2], &[4][..]));
        assert_eq!(v.with_capacity_of(0), Err(Full { capacity: 0 }));
        assert_eq!(v.pop(), Some(4));
        let mut q = BoundedDeque::new(1);
        assert_eq!(q.push_back('a'), Ok(()));
        assert!(q.push_back('b').is_err());
        assert_eq!((q.pop_front(), q.len()), (Some('a'), 0));
    }
}
