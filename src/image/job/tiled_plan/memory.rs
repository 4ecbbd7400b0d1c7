//! The tiled plan's freed memory handed back to the system after each tile and each commit.
//!
//! A tile's fit allocates and frees tens of megabytes (its window's samples, kernel rows,
//! PCG's vectors) in the allocator's arena of the thread that ran it. glibc keeps what is
//! freed inside its arenas for reuse and returns to the system only the top of an arena (and
//! never the top where the binary's `main` turns trimming off, src/main.rs): the holes the
//! tiles' fits leave stay resident, and the resident set grows above the bytes live. At
//! 3840x2160 (8 spp, tiles of 128) the heap's peak was 3.56 GB and the peak resident set
//! 4.31 GiB (docs/measurements/scale-out.md). After each tile, and after a round's commit
//! (which frees the replaced tile states and the tiles' positions, about half a gigabyte at
//! 3840x2160, held through the caller's render otherwise), `malloc_trim(0)` hands the whole
//! pages of every free block in every arena back (`madvise`), so the resident set follows the
//! bytes live: the next tile faults its pages in again. What it cannot hand back: free pieces
//! smaller than a page between live blocks, and the free top of a thread's arena. Nothing
//! computed changes: positions and images are bit for bit the same.

/// Returns the whole free pages of every glibc arena to the system (`malloc_trim(0)`); a
/// no-op with another allocator or system.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
pub(super) fn release_freed_memory() {
    // SAFETY: `malloc_trim` only releases pages of free blocks, under each arena's lock; its
    // result (whether anything was released) needs no action.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Returns the whole free pages of every glibc arena to the system: a no-op here.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
pub(super) fn release_freed_memory() {}
