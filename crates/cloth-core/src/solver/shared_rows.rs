//! The explicit fast path's row-blocked state, read and updated in place by several bands at
//! once.
//!
//! On a large cloth the fast path updates its state in place ([`super::grid_kernel`]): each
//! band reads old rows and overwrites the rows it has finished with, while the other bands
//! read their own rows and their neighbours' boundary rows. Shared and mutable slices of one
//! array cannot express that split (which rows are read and which written changes row by
//! row), so the array is handed to the bands as a pointer, [`SharedRows`], and every access
//! states which floats it touches. The protocol that keeps the accesses apart is the bands'
//! ([`super::grid_kernel::band`]): a band writes a row only after its last read of it, and the
//! rows its neighbours read (its first three and last two, next to another band) are written
//! after the bands join.
#![allow(unsafe_code)]

use std::marker::PhantomData;

/// A `f32` array borrowed for one substep, read and written by range (see the module docs).
#[derive(Clone, Copy)]
pub(crate) struct SharedRows<'a> {
    ptr: *mut f32,
    len: usize,
    /// Whether it was made from a mutable borrow ([`SharedRows::put`] is allowed).
    writable: bool,
    _borrow: PhantomData<&'a mut [f32]>,
}

// SAFETY: the pointer is to `f32`s borrowed for `'a`; sharing it between threads is what the
// type is for, and every access is through `get` and `put`, whose contracts exclude a write
// concurrent with any other access to the same floats.
unsafe impl Send for SharedRows<'_> {}
// SAFETY: as for `Send`.
unsafe impl Sync for SharedRows<'_> {}

impl<'a> SharedRows<'a> {
    /// Reads only ([`SharedRows::put`] panics).
    pub(crate) fn reader(rows: &'a [f32]) -> Self {
        Self {
            ptr: rows.as_ptr().cast_mut(),
            len: rows.len(),
            writable: false,
            _borrow: PhantomData,
        }
    }

    /// Reads and writes.
    pub(crate) fn writer(rows: &'a mut [f32]) -> Self {
        Self {
            ptr: rows.as_mut_ptr(),
            len: rows.len(),
            writable: true,
            _borrow: PhantomData,
        }
    }

    /// Floats `at .. at + len`.
    ///
    /// # Safety
    /// Nothing writes these floats (through [`SharedRows::put`]) while the slice is alive.
    ///
    /// # Panics
    /// When the range is out of bounds.
    #[inline]
    pub(crate) unsafe fn get(&self, at: usize, len: usize) -> &'a [f32] {
        assert!(
            at <= self.len && len <= self.len - at,
            "range out of bounds"
        );
        // SAFETY: in bounds of the borrowed array (checked); no concurrent write (contract).
        unsafe { std::slice::from_raw_parts(self.ptr.add(at), len) }
    }

    /// Copies `src` into floats `at .. at + src.len()`.
    ///
    /// # Safety
    /// No slice from [`SharedRows::get`] covering any of these floats is alive, and no other
    /// thread reads or writes them until the substep's bands have joined.
    ///
    /// # Panics
    /// When the range is out of bounds or the rows were borrowed for reading only.
    #[inline]
    pub(crate) unsafe fn put(&self, at: usize, src: &[f32]) {
        assert!(self.writable, "rows borrowed for reading");
        assert!(
            at <= self.len && src.len() <= self.len - at,
            "range out of bounds"
        );
        // SAFETY: in bounds of the mutably borrowed array (checked); nobody else accesses
        // these floats now (contract); `src` is not part of them (it is borrowed separately).
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), self.ptr.add(at), src.len()) }
    }
}

#[cfg(test)]
mod tests {
    use super::SharedRows;

    #[test]
    fn get_reads_what_put_wrote_and_ranges_are_checked() {
        let mut a = vec![0.0_f32; 8];
        let rows = SharedRows::writer(&mut a);
        // SAFETY: one thread, no slice alive across the write.
        unsafe {
            rows.put(2, &[1.0, 2.0]);
            assert_eq!(rows.get(1, 3), &[0.0, 1.0, 2.0]);
        }
        assert_eq!(a, [0.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
        let b = [1.0_f32; 4];
        let read = SharedRows::reader(&b);
        // SAFETY: nothing writes `b`.
        let out = std::panic::catch_unwind(|| unsafe { read.get(3, 2).len() });
        assert!(out.is_err(), "out of bounds");
        let out = std::panic::catch_unwind(|| unsafe { read.put(0, &[2.0]) });
        assert!(out.is_err(), "reader");
    }
}
