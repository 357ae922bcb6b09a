//! The one piece of unsafe parallel plumbing: a slice that several rayon tasks write to at
//! indices they own exclusively (radix-sort scatter, bottom-up refit). Callers state in a
//! `SAFETY` comment why no index is touched by two threads at once.

use std::marker::PhantomData;

pub(crate) struct UnsafeSlice<'a, T> {
    ptr: *mut T,
    len: usize,
    _borrow: PhantomData<&'a mut [T]>,
}

// SAFETY: access is only through the unsafe methods below, whose callers guarantee
// exclusive access per index.
unsafe impl<T: Send> Send for UnsafeSlice<'_, T> {}
unsafe impl<T: Send> Sync for UnsafeSlice<'_, T> {}

impl<'a, T> UnsafeSlice<'a, T> {
    pub(crate) fn new(slice: &'a mut [T]) -> Self {
        Self { ptr: slice.as_mut_ptr(), len: slice.len(), _borrow: PhantomData }
    }

    /// # Safety
    /// No other thread may read or write index `i` concurrently.
    #[inline(always)]
    pub(crate) unsafe fn write(&self, i: usize, value: T) {
        assert!(i < self.len);
        self.ptr.add(i).write(value);
    }

    /// A raw pointer to element `i`, for field-level access.
    ///
    /// # Safety
    /// The caller must not create overlapping references through it; every read or write of
    /// a field must be exclusive of concurrent writes to that field.
    #[inline(always)]
    pub(crate) unsafe fn ptr(&self, i: usize) -> *mut T {
        assert!(i < self.len);
        self.ptr.add(i)
    }
}
