//! The shield profile's core policy (`firmware_plc::field_io::Shield`) against g431-emu's
//! models of the X-NUCLEO-PLC01A1's chips, which are written from the datasheets and not
//! from the firmware (`g431-emu/docs/models.md`): two independent readings of the same
//! frames must agree, and each fault must reach its code with the outputs off. The
//! emulated SPI1 between them is not modelled yet, so the bus here is a direct call.

use firmware_plc::field_io::{FieldFault, Shield, SpiPort};
use g431_emu::devices::clt01_38sq7::{Clt01_38sq7, FieldSupply};
use g431_emu::devices::vni8200xp::Vni8200xp;

/// The shield's bus: one chip select each, OUT_EN wired to the VNI8200XP.
struct ShieldBoard {
    inputs: Clt01_38sq7,
    outputs: Vni8200xp,
}

impl ShieldBoard {
    fn new() -> Self {
        ShieldBoard {
            inputs: Clt01_38sq7::new(),
            outputs: Vni8200xp::new(),
        }
    }
}

impl SpiPort for ShieldBoard {
    fn exchange_inputs(&mut self) -> u16 {
        self.inputs.exchange(16)
    }
    fn exchange_outputs(&mut self, command: u16) -> u16 {
        self.outputs.exchange(command, 16)
    }
    fn set_out_enable(&mut self, on: bool) {
        self.outputs.out_enable = on;
    }
}

/// One 1 ms pass as the board makes it: inputs, then the outputs `image`.
fn pass(shield: &mut Shield, board: &mut ShieldBoard, image: u8) -> u8 {
    let d = shield.read_inputs(board);
    shield.write_outputs(image, board);
    d
}

/// A shield running for `ms` with the program's image `image` (the DC-DC's start-up
/// passes included).
fn running(image: u8, ms: u32) -> (Shield, ShieldBoard) {
    let mut shield = Shield::new();
    let mut board = ShieldBoard::new();
    for _ in 0..ms {
        let _ = pass(&mut shield, &mut board, image);
    }
    assert_eq!(shield.take_trip(), None, "a healthy shield never trips");
    (shield, board)
}

#[test]
fn inputs_reach_the_core_and_outputs_follow_it() {
    let (mut shield, mut board) = running(0x00, 20);
    for inputs in [0x01u8, 0x80, 0x5A, 0xFF, 0x00] {
        board.inputs.inputs = inputs;
        let image = inputs.rotate_left(1);
        assert_eq!(pass(&mut shield, &mut board, image), inputs);
        assert_eq!(board.outputs.outputs(), image);
        assert!(!board.outputs.fault_pin_low());
    }
    assert_eq!(
        board.outputs.refused(),
        0,
        "every command passed the chip's own check"
    );
    assert_eq!(shield.take_trip(), None);
}

#[test]
fn a_channel_in_thermal_shutdown_trips_200_with_every_output_off() {
    let (mut shield, mut board) = running(0x0F, 20);
    assert_eq!(board.outputs.outputs(), 0x0F);
    board.outputs.overheated = 0x02;
    let _ = pass(&mut shield, &mut board, 0x0F);
    assert_eq!(board.outputs.outputs(), 0, "OUT_EN low");
    let fault = shield.take_trip();
    assert_eq!(fault, Some(FieldFault::OutputOvertemp));
    assert_eq!(fault.map(FieldFault::code), Some(200));
    // The cause gone, outputs stay off until RUN rearms the shield.
    board.outputs.overheated = 0;
    let _ = pass(&mut shield, &mut board, 0x0F);
    assert_eq!(board.outputs.outputs(), 0);
    shield.rearm();
    let _ = pass(&mut shield, &mut board, 0x0F);
    let _ = pass(&mut shield, &mut board, 0x0F);
    assert_eq!(board.outputs.outputs(), 0x0F);
    assert_eq!(shield.take_trip(), None);
}

#[test]
fn a_24v_loss_trips_201_with_every_output_off() {
    let (mut shield, mut board) = running(0xF0, 20);
    board.inputs.inputs = 0x03;
    board.inputs.supply = FieldSupply::Low;
    board.outputs.supply_ok = false;
    assert_eq!(
        pass(&mut shield, &mut board, 0xF0),
        0,
        "no input reaches the program"
    );
    assert_eq!(board.outputs.outputs(), 0);
    assert!(!board.outputs.out_enable);
    assert_eq!(shield.take_trip().map(FieldFault::code), Some(201));
}

#[test]
fn a_dead_input_chip_trips_203_after_one_retry() {
    let (mut shield, mut board) = running(0x01, 20);
    let before = board.inputs.frames();
    board.inputs.supply = FieldSupply::Off;
    assert_eq!(pass(&mut shield, &mut board, 0x01), 0);
    assert_eq!(board.inputs.frames() - before, 2, "read, retried once");
    assert_eq!(board.outputs.outputs(), 0);
    assert_eq!(shield.take_trip().map(FieldFault::code), Some(203));
}

#[test]
fn the_input_chip_overheating_trips_202() {
    let (mut shield, mut board) = running(0x01, 20);
    board.inputs.over_temperature = true;
    let _ = pass(&mut shield, &mut board, 0x01);
    assert_eq!(board.outputs.outputs(), 0);
    assert_eq!(shield.take_trip().map(FieldFault::code), Some(202));
}
