// The slave board's update rate, a build setting: `OMNIBENCH_SLAVE_RATE_HZ` (one of
// `BOARD_RATES_HZ`; `DEFAULT_RATE_HZ` when unset). The build script checks it and writes the
// period for `src/main.rs`; the library exports the rates (the emulator's `--slave-rate` takes
// the same) and its tests check the check. (`include!`d by the build script: Cargo shares no
// code between a build script and its package without a crate of its own.)

/// The rates the slave runs at, Hz.
pub const BOARD_RATES_HZ: [u32; 4] = [1000, 2000, 5000, 10000];

/// The rate of a board built without the setting, Hz.
pub const DEFAULT_RATE_HZ: u32 = 1000;

/// The update period at `hz`, µs, if the slave runs at that rate.
pub fn period_us(hz: u32) -> Option<u32> {
    BOARD_RATES_HZ.contains(&hz).then(|| 1_000_000 / hz)
}

/// The update period, µs, for the setting's value (`None`: unset, [`DEFAULT_RATE_HZ`]); `None`
/// for anything but one of [`BOARD_RATES_HZ`].
pub fn board_period_us(setting: Option<&str>) -> Option<u32> {
    match setting {
        None => period_us(DEFAULT_RATE_HZ),
        Some(text) => text.trim().parse().ok().and_then(period_us),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_rate_gives_its_period_and_anything_else_is_refused() {
        assert_eq!(board_period_us(None), Some(1_000));
        let periods: Vec<_> = ["1000", "2000", "5000", " 10000 "]
            .iter()
            .map(|s| board_period_us(Some(s)))
            .collect();
        assert_eq!(periods, [Some(1_000), Some(500), Some(200), Some(100)]);
        for bad in ["", "3000", "100000", "10 kHz", "-1000"] {
            assert_eq!(board_period_us(Some(bad)), None, "{bad:?}");
        }
    }
}
