//! The binary's heap: glibc's allocator, one heap for every thread, keeping freed memory for
//! reuse, on transparent huge pages.
//!
//! Each `rkwave` call is a fresh process (the renderer loop runs one `plan` call per round),
//! so every page it touches is touched for the first time: one fault a 4 KB page, the kernel
//! zeroing it, and the fit's scattered reads (the tree operator's rows and columns) miss the
//! TLB over tens of megabytes. The heap is advised `MADV_HUGEPAGE` as it grows ([`Heap`]):
//! its first touch of a 2 MB page faults the whole of it at once (512 times fewer faults),
//! and a TLB entry covers 512 times more. This is glibc's own `glibc.malloc.hugetlb=1`
//! tunable, which only the environment can set before the process starts; measured in
//! docs/measurements/plan-speed.md ("The per-call cost"). The values computed are the same
//! bit for bit: only where the memory comes from changes. Without transparent huge pages
//! (`/sys/kernel/mm/transparent_hugepage/enabled` set to `never`) the advice is ignored.

use std::alloc::{GlobalAlloc, Layout, System};
#[cfg(all(target_os = "linux", target_env = "gnu"))]
use std::sync::atomic::{AtomicUsize, Ordering};

/// The size of a transparent huge page on x86-64 (and aarch64 with 4 KB pages).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const HUGE_PAGE: usize = 2 << 20;

/// How far the heap grows at least each time it grows (glibc's `M_TOP_PAD`): large steps, so
/// that the huge pages of a step lie inside the heap before they are first touched. Address
/// space only: a page is resident once touched.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const HEAP_STEP: i32 = 64 << 20;

/// The end of the heap's part advised so far (0: nothing yet, before [`configure`]).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
static ADVISED: AtomicUsize = AtomicUsize::new(0);

#[cfg(all(target_os = "linux", target_env = "gnu"))]
extern "C" {
    /// glibc's `sbrk`: with 0, the heap's current end (no system call).
    fn sbrk(increment: libc::intptr_t) -> *mut libc::c_void;
}

/// The system allocator, its heap advised as transparent huge pages as it grows, and each
/// block mapped apart (32 MB or more) advised likewise (module docs).
pub struct Heap;

// SAFETY: every block comes from `System` and goes back to it with the layout it was made
// with; the advice only sets how the kernel backs memory the allocator owns.
unsafe impl GlobalAlloc for Heap {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let block = unsafe { System.alloc(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let block = unsafe { System.alloc_zeroed(layout) };
        advise(block, layout.size());
        block
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: the caller's contract, passed on.
        let block = unsafe { System.realloc(ptr, layout, new_size) };
        advise(block, new_size);
        block
    }
}

/// After a block of `size` bytes at `block` was allocated: the heap's part grown since the
/// last advice, and the huge pages a block of at least one huge page covers whole (a block
/// mapped apart, outside the heap), advised `MADV_HUGEPAGE`. Blocks below a page cannot have
/// grown the heap by more than glibc's step, which the next larger block advises. A refusal
/// (a kernel without transparent huge pages) leaves the pages as they are, still correct.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn advise(block: *mut u8, size: usize) {
    if block.is_null() || size < 4096 {
        return;
    }
    let advised = ADVISED.load(Ordering::Relaxed);
    if advised != 0 {
        // SAFETY: `sbrk(0)` only reads the heap's end.
        let end = unsafe { sbrk(0) } as usize;
        if end > advised && ADVISED.fetch_max(end, Ordering::Relaxed) < end {
            // SAFETY: `advised..end` is the heap's part grown since, owned by the allocator;
            // the advice changes how its pages are backed, not their contents.
            let from = advised & !4095;
            unsafe {
                libc::madvise(from as *mut libc::c_void, end - from, libc::MADV_HUGEPAGE);
            }
        }
    }
    if size >= HUGE_PAGE {
        let start = (block as usize).next_multiple_of(HUGE_PAGE);
        let end = (block as usize + size) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            // SAFETY: `start..end` lies inside the block just allocated.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
}

/// Elsewhere no advice.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn advise(_: *mut u8, _: usize) {}

/// Sets glibc's allocator for the command's work, before any other thread exists:
///
/// * freed memory is kept in the heap for reuse instead of returned to the system: blocks up
///   to 32 MB come from the heap instead of a fresh `mmap` each, and the heap's top is never
///   trimmed. The PCG iterations allocate and free vectors of 8-112 MB (a channel's
///   coefficients, the samples' values); from fresh mappings each one paid its page faults
///   again. The price is a higher peak resident size (freed memory is held until the process
///   ends); both figures: docs/measurements/plan-speed.md, "Adaptive image sampling: speed
///   and memory";
/// * one heap (arena) for every thread, grown in steps of [`HEAP_STEP`] and advised as huge
///   pages from here on (module docs): the worker threads' blocks come from the same heap
///   (glibc's per-thread caches still serve small blocks without a lock).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub fn configure() {
    // SAFETY: `mallopt` only sets the allocator's parameters; it runs before any other thread
    // exists and its failure (a 0 return) leaves glibc's defaults, which are still correct.
    // `sbrk(0)` only reads the heap's end.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
        libc::mallopt(libc::M_TOP_PAD, HEAP_STEP);
        libc::mallopt(libc::M_ARENA_MAX, 1);
        ADVISED.store(sbrk(0) as usize, Ordering::Relaxed);
    }
}

/// Elsewhere the system allocator keeps its defaults.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub fn configure() {}
