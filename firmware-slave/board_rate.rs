// The slave board's update rate, a build setting: `OMNIBENCH_SLAVE_RATE_HZ` (1000, 2000, 5000
// or 10000; 1000 when unset). The build script checks it and writes the period for
// `src/main.rs`; the library's tests check the check. (`include!`d by both: Cargo shares no
// code between a build script and its package without a crate of its own.)

/// The rates the slave runs at, Hz (the emulator's `--slave-rate` takes the same).
pub const BOARD_RATES_HZ: [u32; 4] = [1000, 2000, 5000, 10000];

/// The update period, µs, for the setting's value (`None`: unset), or why it is refused.
pub fn board_period_us(setting: Option<&str>) -> Result<u32, String> {
    let Some(text) = setting else {
        return Ok(1_000);
    };
    match text.trim().parse::<u32>() {
        Ok(hz) if BOARD_RATES_HZ.contains(&hz) => Ok(1_000_000 / hz),
        _ => Err(format!(
            "OMNIBENCH_SLAVE_RATE_HZ={text:?}: the slave's update rate is one of {BOARD_RATES_HZ:?} \
             Hz (unset: 1000)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_rate_gives_its_period_and_anything_else_is_refused_by_name() {
        assert_eq!(board_period_us(None), Ok(1_000));
        let periods: Vec<_> = ["1000", "2000", "5000", " 10000 "]
            .iter()
            .map(|s| board_period_us(Some(s)))
            .collect();
        assert_eq!(periods, [Ok(1_000), Ok(500), Ok(200), Ok(100)]);
        for bad in ["", "3000", "100000", "10 kHz", "-1000"] {
            let e = board_period_us(Some(bad)).unwrap_err();
            assert!(
                e.contains("OMNIBENCH_SLAVE_RATE_HZ") && e.contains("10000"),
                "{e}"
            );
        }
    }
}
