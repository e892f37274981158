//! Service integration tests: one binary (style.md: zero-to-production), an app per test.

mod crash;
mod datasets;
mod errors;
mod helpers;
mod jobs;
