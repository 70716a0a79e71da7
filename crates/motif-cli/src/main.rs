//! The `motif` command-line tool.
fn main() {}
