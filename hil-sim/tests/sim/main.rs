//! hil-sim's scenario and command-line tests, in one test binary (each integration test
//! binary is a separate fat-LTO link in the release profile the README tests with).

#![allow(dead_code)]

mod common;

mod brake_and_determinism;
mod campaign;
mod cli;
mod debounce;
mod drive_bodies;
mod examples_on_rig;
mod field_io;
mod hw_comparators;
mod keypad;
mod lab;
mod lift;
mod lift_plant;
mod link_latency;
mod motor_program;
mod overmodulation;
mod plc_task;
mod reversal;
mod safety;
mod service;
mod settings;
mod shipped_scenarios;
mod trips;
mod warnings;
