//! The application on rigs (the co-simulation pair with the drive's application, the
//! service line): unit tests, because they step the application's single steps (scan,
//! key, storage, render), which are test-only (`PlcApp`'s public face is the board's
//! pass, `task::AppPass`).

mod link_app;
mod service;
mod service_clock;
mod service_counters;
mod service_support;
mod service_write;
