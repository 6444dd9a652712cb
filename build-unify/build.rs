//! Empty: it exists so that the build-dependencies above are part of the build.
fn main() {}
