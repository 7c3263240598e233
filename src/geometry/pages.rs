//! The storage of the BVH's nodes and blocks: an array that asks the operating system for huge
//! pages where it is large enough to use them.
//!
//! A ray through a million triangles reads a few dozen nodes and blocks scattered over tens of
//! megabytes. With 4 KiB pages nearly every one of those reads needs its own translation, more
//! than the processor's translation cache holds, so each costs a page-table walk on top of the
//! cache miss. A 2 MiB page covers 512 times as much: the whole hierarchy then needs a few dozen
//! translations. On Linux, whose transparent huge pages are commonly given only to memory that
//! asks for them (`madvise` mode), the array is allocated on a 2 MiB boundary and marked with
//! `MADV_HUGEPAGE` before it is written. Elsewhere, for small arrays, or where the kernel
//! declines, it is an ordinary allocation: what is stored and read is the same either way.
//! Book: "Measuring a renderer" ("Against Embree, ray for ray").

use std::alloc::{self, Layout};
use std::fmt;
use std::ops::Deref;
use std::ptr::NonNull;

/// The size of a huge page on x86-64 and AArch64 Linux.
pub const HUGE_PAGE: usize = 2 << 20;

/// An immutable array of `T`, in huge pages when it spans at least one ([`HUGE_PAGE`]).
/// Reading it is a slice's pointer and length either way: traversal reads nodes and blocks
/// through it once a node, so the kind of allocation is kept out of that path.
pub struct Pages<T: Copy> {
    ptr: NonNull<T>,
    len: usize,
    /// `Some(layout)`: allocated here with `layout` (aligned to [`HUGE_PAGE`]); `None`: an
    /// ordinary boxed slice, given back to its `Box` on drop.
    huge: Option<Layout>,
}

// SAFETY: `Pages` owns its values as a `Box<[T]>` would and hands out only shared references.
unsafe impl<T: Copy + Send> Send for Pages<T> {}
// SAFETY: as above; nothing is written after construction.
unsafe impl<T: Copy + Sync> Sync for Pages<T> {}

impl<T: Copy> Pages<T> {
    /// A copy of `values`.
    pub fn new(values: &[T]) -> Self {
        let bytes = std::mem::size_of_val(values);
        if bytes < HUGE_PAGE || !cfg!(target_os = "linux") {
            return Self::boxed(values);
        }
        let Ok(layout) = Layout::from_size_align(bytes, HUGE_PAGE.max(std::mem::align_of::<T>()))
        else {
            return Self::boxed(values);
        };
        // SAFETY: the layout's size is at least HUGE_PAGE, not zero
        let Some(ptr) = NonNull::new(unsafe { alloc::alloc(layout) }.cast::<T>()) else {
            return Self::boxed(values);
        };
        advise_huge(ptr.as_ptr().cast(), layout.size());
        // SAFETY: the allocation holds `values.len()` values of T, aligned for T, and does not
        // overlap `values`
        unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), ptr.as_ptr(), values.len()) };
        Pages {
            ptr,
            len: values.len(),
            huge: Some(layout),
        }
    }

    fn boxed(values: &[T]) -> Self {
        let len = values.len();
        let raw = Box::into_raw(Box::<[T]>::from(values));
        Pages {
            // SAFETY: a box's pointer is never null (dangling but aligned when empty)
            ptr: unsafe { NonNull::new_unchecked(raw.cast::<T>()) },
            len,
            huge: None,
        }
    }

    /// Whether the values were placed in memory marked for huge pages (the kernel decides
    /// whether it backs them with huge pages).
    pub fn huge(&self) -> bool {
        self.huge.is_some()
    }
}

/// Asks the kernel to back `[ptr, ptr + len)` with huge pages; a refusal leaves ordinary pages.
#[cfg(target_os = "linux")]
fn advise_huge(ptr: *mut libc::c_void, len: usize) {
    // SAFETY: the range is one live allocation of ours, aligned to a page; the advice changes
    // how it is backed, never its contents
    unsafe { libc::madvise(ptr, len, libc::MADV_HUGEPAGE) };
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_ptr: *mut std::ffi::c_void, _len: usize) {}

impl<T: Copy> Deref for Pages<T> {
    type Target = [T];

    #[inline]
    fn deref(&self) -> &[T] {
        // SAFETY: `ptr` holds `len` initialized values, alive as long as `self`
        unsafe { std::slice::from_raw_parts(self.ptr.as_ptr(), self.len) }
    }
}

impl<T: Copy> Drop for Pages<T> {
    fn drop(&mut self) {
        match self.huge {
            // SAFETY: allocated in `new` with this layout, freed once
            Some(layout) => unsafe { alloc::dealloc(self.ptr.as_ptr().cast(), layout) },
            // SAFETY: made by `Box::into_raw` of a slice of `len` values in `boxed`, freed once
            None => unsafe {
                drop(Box::from_raw(std::ptr::slice_from_raw_parts_mut(
                    self.ptr.as_ptr(),
                    self.len,
                )))
            },
        }
    }
}

impl<T: Copy> Default for Pages<T> {
    fn default() -> Self {
        Self::boxed(&[])
    }
}

impl<T: Copy> Clone for Pages<T> {
    fn clone(&self) -> Self {
        Self::new(self)
    }
}

impl<T: Copy + fmt::Debug> fmt::Debug for Pages<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small and large arrays read back what they were made from, clones included; a large
    /// one is placed in memory marked for huge pages on Linux, and a kernel with transparent
    /// huge pages has the mark (`hg` among the mapping's flags in `/proc/self/smaps`).
    #[test]
    fn pages_hold_what_they_were_given() {
        for n in [0usize, 1, 1000, HUGE_PAGE / 4 + 3] {
            let values: Vec<u32> = (0..n as u32)
                .map(|i| i.wrapping_mul(2_654_435_761))
                .collect();
            let pages = Pages::new(&values);
            assert_eq!(&pages[..], &values[..]);
            assert_eq!(&pages.clone()[..], &values[..]);
            let large = n * 4 >= HUGE_PAGE;
            assert_eq!(pages.huge(), large && cfg!(target_os = "linux"), "{n}");
            // (a kernel built without transparent huge pages refuses the advice)
            #[cfg(target_os = "linux")]
            if large && std::path::Path::new("/sys/kernel/mm/transparent_hugepage").exists() {
                let flags = mapping_flags(pages.as_ptr() as usize).expect("a mapping");
                assert!(flags.split_whitespace().any(|f| f == "hg"), "{flags}");
            }
        }
        assert!(Pages::<[f32; 64]>::default().is_empty());
        assert_eq!(format!("{:?}", Pages::new(&[1u8, 2])), "[1, 2]");
    }

    /// Dropped pages give their memory back: a process that builds scene after scene (the
    /// Python module, a converge run) must not grow. Four arrays of 64 MiB, each written in
    /// full and dropped, leave the resident set within one array of where it started; kept,
    /// they would add 256 MiB.
    #[cfg(target_os = "linux")]
    #[test]
    fn dropped_pages_give_their_memory_back() {
        let resident = || -> usize {
            let statm = std::fs::read_to_string("/proc/self/statm").expect("statm");
            let pages: usize = statm.split_whitespace().nth(1).unwrap().parse().unwrap();
            pages * 4096
        };
        let values = vec![7u8; 64 << 20];
        let before = resident();
        for _ in 0..4 {
            let pages = Pages::new(&values);
            assert!(pages.huge() && pages[(64 << 20) - 1] == 7);
        }
        let grown = resident().saturating_sub(before);
        assert!(grown < 64 << 20, "resident set grew by {} MiB", grown >> 20);
    }

    /// The `VmFlags` of the mapping of this process that holds `address`.
    #[cfg(target_os = "linux")]
    fn mapping_flags(address: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            let range = line
                .split_whitespace()
                .next()
                .and_then(|r| r.split_once('-'));
            let bounds = range.and_then(|(a, b)| {
                Some((
                    usize::from_str_radix(a, 16).ok()?,
                    usize::from_str_radix(b, 16).ok()?,
                ))
            });
            if let Some((lo, hi)) = bounds {
                inside = (lo..hi).contains(&address);
            } else if let (true, Some(flags)) = (inside, line.strip_prefix("VmFlags:")) {
                return Some(flags.to_string());
            }
        }
        None
    }
}
