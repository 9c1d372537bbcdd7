//! Is the chip behind a probe the one we are about to flash for?
//!
//! probe-rs attaches with whatever chip description it is told and does not check the silicon,
//! so a probe wired to the wrong board would get an image built for another part. Before
//! flashing we read two ID registers over the debug port and compare them with what the chip
//! name promises:
//! * CPUID (0xE000ED00, every Cortex-M): the core (M3 for the STM32F103);
//! * DBGMCU_IDCODE (0xE0042000 on STM32F1/F2/F4/F7/L1): DEV_ID, the STM32 line and density.
//!
//! Only the STM32F103 family has expectations here (the bench's boards); other chip names are
//! flashed without this check, and say so.

/// Address of the Cortex-M CPUID register.
pub const CPUID_ADDR: u64 = 0xE000_ED00;
/// Address of DBGMCU_IDCODE on STM32F1 (and F2/F4/F7/L1).
pub const DBGMCU_IDCODE_ADDR: u64 = 0xE004_2000;

/// What a chip name promises: the Cortex-M part number and the STM32 DEV_ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Expected {
    pub core_part: u16,
    pub dev_id: u16,
}

/// The expected IDs for a probe-rs chip name, if this module knows the family.
pub fn expected_for(chip: &str) -> Option<Expected> {
    let upper = chip.to_ascii_uppercase();
    let rest = upper.strip_prefix("STM32F103")?;
    // STM32F103 <pins letter> <flash size letter> ...: the flash size sets the density line.
    let size = rest.chars().nth(1)?;
    let dev_id = match size {
        '4' | '6' => 0x412, // low-density
        '8' | 'B' => 0x410, // medium-density (the blue pill's C8 and CB)
        'C' | 'D' | 'E' => 0x414,
        'F' | 'G' => 0x430,
        _ => return None,
    };
    Some(Expected {
        core_part: CORTEX_M3,
        dev_id,
    })
}

const CORTEX_M3: u16 = 0xC23;

fn core_name(part: u16) -> String {
    match part {
        0xC20 => "Cortex-M0".into(),
        0xC60 => "Cortex-M0+".into(),
        0xC21 => "Cortex-M1".into(),
        0xC23 => "Cortex-M3".into(),
        0xC24 => "Cortex-M4".into(),
        0xC27 => "Cortex-M7".into(),
        0xD20 => "Cortex-M23".into(),
        0xD21 => "Cortex-M33".into(),
        other => format!("an unknown core (CPUID part {other:#05x})"),
    }
}

fn stm32_line(dev_id: u16) -> &'static str {
    match dev_id {
        0x412 => "STM32F10x low-density",
        0x410 => "STM32F10x medium-density (e.g. STM32F103C8/CB)",
        0x414 => "STM32F10x high-density",
        0x430 => "STM32F10x XL-density",
        0x418 => "STM32F105/107",
        0x420 => "STM32F100 value line",
        0x411 => "STM32F2xx",
        0x413 => "STM32F405/407/415/417",
        0x419 => "STM32F42x/43x",
        0x431 => "STM32F411",
        0x423 | 0x433 => "STM32F401",
        0x449 | 0x451 | 0x452 => "STM32F7xx",
        0x416 | 0x427 | 0x429 | 0x436 | 0x437 => "STM32L1xx",
        _ => "an unknown STM32 line",
    }
}

/// The verdict on the IDs read from a board.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The IDs match the chip name.
    Matches,
    /// Nothing to compare: unknown family, or the registers read as zero. The text says why;
    /// flashing goes on.
    Unchecked(String),
    /// The board carries another chip; the text says what was found and what was expected.
    Mismatch(String),
}

/// Compares the CPUID and DBGMCU_IDCODE read from a board with what `chip` promises.
pub fn judge(chip: &str, cpuid: u32, idcode: u32) -> Verdict {
    let Some(expected) = expected_for(chip) else {
        return Verdict::Unchecked(format!(
            "no ID check for {chip} (only the STM32F103 family is known to host-bench)"
        ));
    };
    if cpuid == 0 {
        // A real Cortex-M never reads CPUID as 0: the read did not reach the core.
        return Verdict::Unchecked("CPUID read as 0; the chip was not identified".into());
    }
    let part = ((cpuid >> 4) & 0xFFF) as u16;
    let dev_id = (idcode & 0xFFF) as u16;
    let expected_text = format!(
        "{chip} ({}, DEV_ID {:#05x})",
        core_name(expected.core_part),
        expected.dev_id
    );
    if part != expected.core_part {
        return Verdict::Mismatch(format!(
            "found {} (CPUID {cpuid:#010x}), expected {expected_text}; is this probe wired to \
             the right board, and is --chip / bench.toml's chip right?",
            core_name(part)
        ));
    }
    if dev_id != expected.dev_id {
        return Verdict::Mismatch(format!(
            "found {} (DEV_ID {dev_id:#05x}, DBGMCU_IDCODE {idcode:#010x}), expected \
             {expected_text}; is --chip / bench.toml's chip right?",
            stm32_line(dev_id)
        ));
    }
    Verdict::Matches
}

#[cfg(test)]
mod tests {
    use super::*;

    const BLUE_PILL_CPUID: u32 = 0x411F_C231;

    #[test]
    fn a_blue_pill_matches_its_chip_name() {
        assert_eq!(
            judge("STM32F103C8", BLUE_PILL_CPUID, 0x2000_6410),
            Verdict::Matches
        );
        assert_eq!(
            judge("stm32f103cbtx", BLUE_PILL_CPUID, 0x2000_6410),
            Verdict::Matches
        );
    }

    #[test]
    fn another_chip_is_named_with_what_was_expected() {
        let Verdict::Mismatch(m) = judge("STM32F103C8", 0x410F_C241, 0x1000_6413) else {
            panic!("an STM32F407 passed as an STM32F103C8");
        };
        assert!(
            m.contains("Cortex-M4") && m.contains("expected STM32F103C8"),
            "{m}"
        );
        let Verdict::Mismatch(m) = judge("STM32F103C8", BLUE_PILL_CPUID, 0x1000_6414) else {
            panic!("a high-density F103 passed as a C8");
        };
        assert!(m.contains("high-density") && m.contains("0x410"), "{m}");
    }

    #[test]
    fn unknown_families_and_unread_registers_are_not_judged() {
        assert!(matches!(
            judge("nRF52840_xxAA", 0x410F_C241, 0),
            Verdict::Unchecked(_)
        ));
        assert!(matches!(judge("STM32F103C8", 0, 0), Verdict::Unchecked(_)));
    }
}
