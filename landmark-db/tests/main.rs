//! The database binary and store from outside: the CLI, a killed writer, many writers.

mod cli;
mod crash;
mod stress;
