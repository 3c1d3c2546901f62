//! AFL target: [`phenomena_fuzz::checkpoint`] (see the crate docs for how to run it).
#![allow(missing_docs)]

fn main() {
    afl::fuzz!(|data: &[u8]| phenomena_fuzz::checkpoint(data));
}
