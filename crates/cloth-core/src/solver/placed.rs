//! Arrays of the grid paths placed at chosen offsets within a 4 KiB page.
//!
//! The structure-of-arrays state of a 256² cloth is a set of 256 KiB arrays, and the allocator
//! hands such blocks out at the same offset within a page. Entry `i` of every array then has
//! the same address bits 6–11, so it falls into the same set of the 8-way L1 data cache, and a
//! pass that streams more than eight of them at once (positions, start positions, multipliers,
//! rest lengths, inverse masses…) evicts its own lines before it uses them. [`Placed`] starts
//! each array at a different cache line of the page (its slot). Where an array starts changes
//! no result, only which cache sets its lines use.

/// Floats per 4 KiB page.
const PAGE: usize = 1024;

/// Cache lines per page.
const LINES: usize = 64;

/// An `f32` array whose first entry sits at cache line `slot · 5 mod 64` of a 4 KiB page
/// (consecutive slots five lines apart, so 64 slots never share a line), read and written as
/// a slice. The empty default holds nothing until [`Placed::reset`]. A clone is placed on
/// its slot's line again in its own allocation (a copied offset would not be).
#[derive(Debug, Default)]
pub(crate) struct Placed {
    buf: Vec<f32>,
    offset: usize,
    slot: usize,
}

impl Clone for Placed {
    fn clone(&self) -> Self {
        let mut copy = Self::default();
        if !self.buf.is_empty() {
            copy.reset(self.len(), self.slot);
            copy.copy_from_slice(self);
        }
        copy
    }
}

impl Placed {
    /// Where the array lies in the allocation (its length: the allocation less the page of
    /// slack).
    fn range(&self) -> std::ops::Range<usize> {
        self.offset..self.offset + self.buf.len().saturating_sub(PAGE)
    }

    /// Makes the array `len` zeros starting at the page line of `slot` (one page of slack
    /// allocated; reuses the allocation when it is large enough).
    pub(crate) fn reset(&mut self, len: usize, slot: usize) {
        self.buf.clear();
        self.buf.resize(len + PAGE, 0.0);
        let at = (self.buf.as_ptr() as usize / size_of::<f32>()) % PAGE;
        let want = (slot * 5 % LINES) * (PAGE / LINES);
        self.offset = (want + PAGE - at) % PAGE;
        self.slot = slot;
    }
}

impl std::ops::Deref for Placed {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        &self.buf[self.range()]
    }
}

impl std::ops::DerefMut for Placed {
    fn deref_mut(&mut self) -> &mut [f32] {
        let range = self.range();
        &mut self.buf[range]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The array holds `len` zeros at the requested line of a page, whatever the allocation,
    /// and a clone holds the same values at the same line.
    #[test]
    fn reset_places_the_first_entry_on_its_slot_line() {
        let mut a = Placed::default();
        assert!(a.is_empty());
        for slot in [0, 1, 7, 63, 64] {
            a.reset(1000, slot);
            assert_eq!(a.len(), 1000);
            assert!(a.iter().all(|&v| v == 0.0));
            let line = (a.as_ptr() as usize % 4096) / 64;
            assert_eq!(line, slot * 5 % 64, "slot {slot}");
            a[999] = 1.0;
            let b = a.clone();
            assert_eq!(&b[..], &a[..]);
            assert_eq!(
                (b.as_ptr() as usize % 4096) / 64,
                line,
                "clone of slot {slot}"
            );
        }
    }
}
