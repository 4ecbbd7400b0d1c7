//! Damage done to a file a plan keeps in its folder (`pcg.bin`, `rows.bin`, ...), for the tests
//! that the plan sets a damaged file aside with a note and goes on bit for bit.

use std::path::Path;

/// One bit flipped in the middle of the file (its checksum no longer holds).
pub fn flip(f: &Path) {
    let mut b = std::fs::read(f).unwrap();
    let at = b.len() / 2;
    b[at] ^= 0x10;
    std::fs::write(f, b).unwrap();
}

/// The file cut 24 bytes short.
pub fn cut(f: &Path) {
    let b = std::fs::read(f).unwrap();
    std::fs::write(f, &b[..b.len() - 24]).unwrap();
}

/// The file removed.
pub fn remove(f: &Path) {
    std::fs::remove_file(f).unwrap();
}
