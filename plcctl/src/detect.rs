//! Which serial port to use without `--port` (service.md 8): USB ports of an ST-LINK/V3
//! (the NUCLEO-G431RB's STLINK-V3E) only. ST-LINK/V2-1 ports are never opened by
//! themselves: the B-G431B-ESC1's is one, and it is wired to the PLC-drive link.

use serialport::{SerialPortInfo, SerialPortType};

use crate::fail::{Fail, Result};

/// STMicroelectronics' USB vendor ID.
pub const ST_VID: u16 = 0x0483;
/// ST-LINK/V3 product IDs with a virtual COM port (STLINK-V3E/V3SET/V3MINI variants).
pub const STLINK_V3_PIDS: [u16; 4] = [0x374E, 0x374F, 0x3753, 0x3754];

/// Whether a port is an ST-LINK/V3 virtual COM port.
pub fn is_stlink_v3(info: &SerialPortInfo) -> bool {
    matches!(&info.port_type, SerialPortType::UsbPort(u)
        if u.vid == ST_VID && STLINK_V3_PIDS.contains(&u.pid))
}

/// The one ST-LINK/V3 port among `ports`; none or several: exit 2 with the list.
pub fn choose(ports: &[SerialPortInfo]) -> Result<String> {
    let found: Vec<&SerialPortInfo> = ports.iter().filter(|p| is_stlink_v3(p)).collect();
    match found.as_slice() {
        [one] => Ok(one.port_name.clone()),
        [] => Err(Fail::NoDevice(format!(
            "no ST-LINK/V3 serial port found (USB {ST_VID:04x}:{}); serial ports here: {}; use --port",
            STLINK_V3_PIDS.map(|p| format!("{p:04x}")).join("/"),
            list(ports.iter())
        ))),
        several => Err(Fail::NoDevice(format!(
            "several ST-LINK/V3 serial ports: {}; choose one with --port",
            list(several.iter().copied())
        ))),
    }
}

fn list<'a>(ports: impl Iterator<Item = &'a SerialPortInfo>) -> String {
    let names: Vec<&str> = ports.map(|p| p.port_name.as_str()).collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}

/// The port to use: `--port`, else the one ST-LINK/V3 found.
pub fn port(explicit: Option<&str>) -> Result<String> {
    if let Some(p) = explicit {
        return Ok(p.to_string());
    }
    let ports = serialport::available_ports()
        .map_err(|e| Fail::NoDevice(format!("cannot list serial ports: {e}")))?;
    choose(&ports)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serialport::UsbPortInfo;

    fn usb(name: &str, vid: u16, pid: u16) -> SerialPortInfo {
        SerialPortInfo {
            port_name: name.into(),
            port_type: SerialPortType::UsbPort(UsbPortInfo {
                vid,
                pid,
                serial_number: None,
                manufacturer: None,
                product: None,
            }),
        }
    }

    #[test]
    fn only_one_stlink_v3_is_chosen_and_v2_1_never() {
        let v3 = usb("/dev/ttyACM1", ST_VID, 0x374E);
        let v21 = usb("/dev/ttyACM0", ST_VID, 0x374B);
        let other = usb("/dev/ttyUSB0", 0x0403, 0x6001);
        assert_eq!(
            choose(&[v21.clone(), v3.clone(), other.clone()]).unwrap(),
            "/dev/ttyACM1"
        );
        let none = choose(&[v21.clone(), other]).unwrap_err();
        assert_eq!(none.exit_code(), 2);
        assert!(none.to_string().contains("/dev/ttyACM0"), "{none}");
        let two = choose(&[v3.clone(), usb("/dev/ttyACM2", ST_VID, 0x3753)]).unwrap_err();
        assert_eq!(two.exit_code(), 2);
        assert!(two.to_string().contains("/dev/ttyACM2"), "{two}");
    }
}
