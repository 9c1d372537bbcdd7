"""Timed edges on a board's input pins, from outside: what a robot's encoders do to the slave
(PA0/PA1 and PA8/PA9 quadrature, PB8..PB15 the absolute encoder's Gray code, docs/pinmap.md).

An `EdgeDriver` holds (tick, port, pin, level) rows, sorted; it is one of the chip's timed
sources, so each level change happens at its exact tick (a slice ends there), through
`Gpio.drive`: the pin's IDR bit, EXTI (both edges if the firmware selects them) and the timers'
encoder inputs (`Chip._route_timer_inputs`) all see it as on the chip.

`quadrature(...)` makes the rows of an incremental encoder turning at a constant rate;
`drive_spec("PA0,PA1,START_S,COUNTS,RATE_HZ[,rev]")` the same from a command line;
`load(path)` reads rows from a CSV file `t_us,pin,level` (`pin` as `PA0`, `PB12`, ...).
"""

import csv

from .core import Chip


def pin_of(name):
    """`PA0` -> (0, 0), `PB12` -> (1, 12)."""
    return "ABCDE".index(name[1].upper()), int(name[2:])


QUADRATURE = [(0, 0), (1, 0), (1, 1), (0, 1)]  # (A, B) forward: A leads B by 90 degrees


def quadrature(a, b, start_s, counts, rate_hz, forward=True, levels=(1, 1)):
    """Rows for `counts` quadrature counts (x4: every edge of A or B is one count) at `rate_hz`
    counts per second from `start_s`, A leading B when `forward`, from the lines' present
    `levels` (idle high by default: the slave pulls its encoder inputs up)."""
    pins = (pin_of(a), pin_of(b))
    state = QUADRATURE.index(tuple(levels))
    step = 1 if forward else -1
    rows = []
    for k in range(counts):
        nxt = (state + step) % 4
        line = 0 if QUADRATURE[nxt][0] != QUADRATURE[state][0] else 1
        state = nxt
        port, pin = pins[line]
        t = start_s + k / rate_hz
        rows.append((int(round(t * Chip.TICK_HZ)), port, pin, QUADRATURE[state][line]))
    return rows


def drive_spec(spec):
    """(rows, hold) for `A,B,START_S,COUNTS,RATE_HZ[,rev]`: both lines held high from power-on
    (as `Bench.rest_encoders` holds them), then the counts."""
    f = spec.split(",")
    rows = quadrature(
        f[0],
        f[1],
        float(f[2]),
        int(f[3]),
        float(f[4]),
        forward=not (len(f) > 5 and f[5] == "rev"),
        levels=(1, 1),
    )
    return rows, {pin_of(f[0]): 1, pin_of(f[1]): 1}


def load(path):
    rows = []
    with open(path) as f:
        for r in csv.reader(line for line in f if line.strip() and not line.startswith("#")):
            if r[0] == "t_us":
                continue
            port, pin = pin_of(r[1].strip())
            rows.append((int(round(float(r[0]) * Chip.TICK_HZ / 1e6)), port, pin, int(r[2])))
    return rows


class EdgeDriver:
    """A timed source of pin levels for one chip (see the module's text)."""

    def __init__(self, chip, rows, hold=None):
        """`hold`: {(port, pin): level} driven at once (the encoder is wired from power-on:
        its lines are never floating, so configuring the pins' pulls makes no edge)."""
        self.chip = chip
        for (port, pin), level in (hold or {}).items():
            chip.gpio[port].drive(pin, level)
        self.rows = sorted(rows)
        self.i = 0
        self.applied = 0
        chip.timed.append(self)
        chip.reschedule()

    def next_event(self):
        return self.rows[self.i][0] if self.i < len(self.rows) else None

    def sync(self, now):
        rows, gpio = self.rows, self.chip.gpio
        while self.i < len(rows) and rows[self.i][0] <= now:
            _, port, pin, level = rows[self.i]
            gpio[port].drive(pin, level)
            self.i += 1
            self.applied += 1
        self.chip.reschedule()
