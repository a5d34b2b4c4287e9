//! The PLC-drive link wire format. See link.md.
