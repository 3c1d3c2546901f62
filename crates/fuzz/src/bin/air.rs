//! AFL target: [`phenomena_fuzz::air`] (see the crate docs for how to run it).
#![allow(missing_docs)]

fn main() {
    afl::fuzz!(|data: &[u8]| phenomena_fuzz::air(data));
}
