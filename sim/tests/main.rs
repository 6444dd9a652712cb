//! The simulator binary and its truth from outside.

mod cli;
mod render_truth;
