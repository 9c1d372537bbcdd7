/* The model's hottest register accesses, answered in native code inside unicorn's MMIO
 * callback instead of a Python call (~2 us each; the images make ~600 000 a simulated second).
 *
 * A `fp_page` sits behind one peripheral's MMIO range. Per 32-bit register it says how a
 * read or a write is served:
 *   FP_SLOW    the peripheral's Python model (the callbacks given as `slow_read`/`slow_write`);
 *   FP_MIRROR  (read) the value the Python model last published in `regs`: a register whose
 *              read has no side effect and whose value changes only through the model;
 *   FP_TIM_CNT (read) a timer's counter, computed from the fields the Python model publishes,
 *              the same arithmetic as tim.py's `sync` unless a PSC or ARR preload waits for
 *              the update;
 *   FP_CRC_DR  (write) a word into the CRC unit (RM0008 §4: CRC-32, 0x04C11DB7, MSB first),
 *              whose data register lives in `regs[0]`;
 *   FP_CRC_CR  (write) the CRC unit's control register: RESET (bit 0) sets DR to 0xFFFFFFFF.
 * Anything these cannot answer exactly (a clock-gated peripheral, a timer with a PSC or ARR
 * preload pending, a byte write to the CRC) goes to the Python model, which keeps the
 * definition. So does any read of a timer at or past its next enabled event (`timer_due`, tim.py's
 * `next_event`): there Python's read syncs the timer, which raises the interrupt and ends the
 * slice at that instruction (a timer write inside a slice can bring that event before the
 * slice's end).
 * f103/native.py builds this file and checks the layout below against its ctypes mirror. */

#include <stddef.h>
#include <stdint.h>

enum { FP_SLOW = 0, FP_MIRROR = 1, FP_TIM_CNT = 2, FP_CRC_DR = 3, FP_CRC_CR = 4 };

typedef uint64_t (*fp_read_fn)(void *uc, uint64_t off, unsigned size, void *ud);
typedef void (*fp_write_fn)(void *uc, uint64_t off, unsigned size, uint64_t value, void *ud);

/* The time of the instruction running, as ucfast.FastUc computes it: unicorn's counter of the
 * slice's instructions (1 for its first), the slice's first tick and ticks per instruction. */
struct fp_clock {
    const uint64_t *counter;
    int64_t start;
    double tpi;
};

struct fp_page {
    uint32_t regs[256];
    uint8_t read_kind[256];
    uint8_t write_kind[256];
    fp_read_fn slow_read;
    fp_write_fn slow_write;
    const struct fp_clock *clock;
    uint32_t gate_on; /* the peripheral's RCC clock enable */
    /* a timer, as tim.py's Timer last left it */
    uint32_t tim_div; /* chip ticks per timer-clock cycle */
    uint32_t tim_cr1, tim_smcr, tim_cnt, tim_psc, tim_psc_active, tim_arr, tim_arr_active;
    int64_t tim_anchor;
    uint32_t tim_ccr_active[4];
    uint32_t is_timer; /* the fields above and DIER (regs[3]) are a timer's */
};

static uint32_t crc_table[4][256];

void fp_init(void) {
    for (uint32_t b = 0; b < 256; b++) {
        uint32_t c = b << 24;
        for (int k = 0; k < 8; k++)
            c = (c & 0x80000000u) ? (c << 1) ^ 0x04C11DB7u : c << 1;
        crc_table[0][b] = c;
    }
    for (int t = 1; t < 4; t++)
        for (uint32_t b = 0; b < 256; b++) {
            uint32_t p = crc_table[t - 1][b];
            crc_table[t][b] = (p << 8) ^ crc_table[0][p >> 24];
        }
}

/* sizeof and field offsets, for native.py to check its ctypes mirror against */
size_t fp_layout(int what) {
    switch (what) {
    case 0: return sizeof(struct fp_page);
    case 1: return offsetof(struct fp_page, slow_read);
    case 2: return offsetof(struct fp_page, clock);
    case 3: return offsetof(struct fp_page, tim_anchor);
    case 4: return sizeof(struct fp_clock);
    case 5: return offsetof(struct fp_clock, tpi);
    case 6: return offsetof(struct fp_page, tim_ccr_active);
    case 7: return offsetof(struct fp_page, is_timer);
    default: return 0;
    }
}

uint32_t fp_crc32_word(uint32_t crc, uint32_t word) {
    uint32_t x = crc ^ word;
    return crc_table[3][x >> 24] ^ crc_table[2][(x >> 16) & 0xFF] ^ crc_table[1][(x >> 8) & 0xFF]
        ^ crc_table[0][x & 0xFF];
}

static uint64_t lane(uint32_t reg, uint64_t off, unsigned size) {
    uint32_t v = reg >> ((off & 3) * 8);
    return size >= 4 ? v : v & ((1u << (8 * size)) - 1);
}

/* The tick of the instruction running (FastUc.instruction_time). */
static int64_t now_of(const struct fp_clock *c) {
    return (int64_t)((double)c->start + (double)(*c->counter - 1) * c->tpi);
}

static int timer_running(const struct fp_page *p) {
    uint32_t sms = p->tim_smcr & 7;
    return (p->tim_cr1 & 1) && !(sms >= 1 && sms <= 3);
}

/* tim.py's `next_event`: the tick of the next update or compare match whose interrupt DIER
 * enables, for a running timer; INT64_MAX for none. */
static int64_t timer_due(const struct fp_page *p) {
    uint32_t en = p->regs[0x0C >> 2] & 0x1F;
    if (!en)
        return INT64_MAX;
    int64_t per = (int64_t)p->tim_div * (p->tim_psc_active + 1);
    int64_t mod = (int64_t)p->tim_arr_active + 1;
    int64_t best = INT64_MAX;
    if (en & 1)
        best = ((p->tim_arr_active - p->tim_cnt) & 0xFFFF) + 1;
    for (int i = 0; i < 4; i++) {
        uint32_t c = p->tim_ccr_active[i];
        if ((en & (2u << i)) && c <= p->tim_arr_active) {
            int64_t d = ((int64_t)c - (int64_t)p->tim_cnt) % mod;
            if (d < 0)
                d += mod;
            if (d == 0)
                d = mod;
            if (d < best)
                best = d;
        }
    }
    return best == INT64_MAX ? INT64_MAX : p->tim_anchor + best * per;
}

/* Whether Python must answer a read of this timer now: an enabled event is due, so its sync
 * raises the interrupt. */
static int timer_event_due(const struct fp_page *p) {
    return timer_running(p) && p->clock != NULL && p->tim_div != 0
        && now_of(p->clock) >= timer_due(p);
}

/* tim.py: CNT after `sync(now)`, when the counter runs and no PSC or ARR preload waits for the
 * next update (so the count to `now` is one step of `_advance`) and no enabled event is due;
 * 0 if Python must answer. */
static int timer_cnt(const struct fp_page *p, uint32_t *out) {
    if (!timer_running(p)) {
        *out = p->tim_cnt;
        return 1;
    }
    if (p->tim_psc != p->tim_psc_active || p->tim_arr != p->tim_arr_active || p->clock == NULL
        || p->tim_div == 0)
        return 0;
    int64_t now = now_of(p->clock);
    if (now >= timer_due(p))
        return 0;
    int64_t per = (int64_t)p->tim_div * (p->tim_psc_active + 1);
    int64_t since = now - p->tim_anchor;
    if (since < per) {
        *out = p->tim_cnt;
        return 1;
    }
    uint64_t n = (uint64_t)(since / per);
    uint64_t to_ovf = ((p->tim_arr_active - p->tim_cnt) & 0xFFFF) + 1;
    if (n < to_ovf)
        *out = p->tim_cnt + (uint32_t)n;
    else if (p->tim_cr1 & 8) /* one-pulse mode: stopped at the update */
        *out = 0;
    else
        *out = (uint32_t)((n - to_ovf) % ((uint64_t)p->tim_arr_active + 1));
    return 1;
}

uint64_t fp_read(void *uc, uint64_t off, unsigned size, void *ud) {
    struct fp_page *p = ud;
    unsigned i = (unsigned)(off >> 2) & 0xFF;
    if (p->gate_on) {
        switch (p->read_kind[i]) {
        case FP_MIRROR:
            /* a timer's DIER: Python's read would sync it, raising an event that is due */
            if (p->is_timer && timer_event_due(p))
                break;
            return lane(p->regs[i], off, size);
        case FP_TIM_CNT: {
            uint32_t v;
            if (timer_cnt(p, &v))
                return lane(v, off, size);
            break;
        }
        }
    }
    return p->slow_read(uc, off, size, NULL);
}

void fp_write(void *uc, uint64_t off, unsigned size, uint64_t value, void *ud) {
    struct fp_page *p = ud;
    unsigned i = (unsigned)(off >> 2) & 0xFF;
    if (p->gate_on && size == 4 && (off & 3) == 0) {
        switch (p->write_kind[i]) {
        case FP_CRC_DR:
            p->regs[i] = fp_crc32_word(p->regs[i], (uint32_t)value);
            return;
        case FP_CRC_CR:
            if (value & 1)
                p->regs[0] = 0xFFFFFFFFu;
            return;
        }
    }
    p->slow_write(uc, off, size, value, NULL);
}
