//! hil-sim: runs the firmware cores against a simulated plant in virtual time.

pub mod plant;
