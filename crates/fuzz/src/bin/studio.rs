//! AFL target: [`phenomena_fuzz::studio`] (see the crate docs for how to run it).
#![allow(missing_docs)]

fn main() {
    afl::fuzz!(|data: &[u8]| phenomena_fuzz::studio(data));
}
