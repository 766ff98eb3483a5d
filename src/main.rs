//! The `ellip` command-line tool. (Being written.)
#![forbid(unsafe_code)]

fn main() {}
