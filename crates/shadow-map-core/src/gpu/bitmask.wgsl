// Twin of shadow_map_core::bitmask, in f32 and in the CPU's operation order. Self-contained
// (builtins only). The bit points themselves are the kernel's (a table the CPU fills with
// bitmask::bit_points, so both twins test the same points).

// bitmask::MASK_WORDS (MAX_BITS = 16: 256 bits).
const BITMASK_WORDS: u32 = 8u;

// bitmask::BitMask.
struct BitMask {
    words: array<u32, 8>,
    n_set: u32,
}

fn bitmask_new() -> BitMask {
    var m: BitMask;
    for (var w = 0u; w < BITMASK_WORDS; w++) {
        m.words[w] = 0u;
    }
    m.n_set = 0u;
    return m;
}

// BitMask::is_set.
fn bitmask_is_set(m: ptr<function, BitMask>, k: u32) -> bool {
    return ((*m).words[k / 32u] & (1u << (k % 32u))) != 0u;
}

// BitMask::set (counted once).
fn bitmask_set(m: ptr<function, BitMask>, k: u32) {
    let w = k / 32u;
    let b = 1u << (k % 32u);
    if ((*m).words[w] & b) == 0u {
        (*m).words[w] |= b;
        (*m).n_set += 1u;
    }
}

// BitMask::set_run: bits k0 .. k0 + n (n <= 32), counting only those newly set.
fn bitmask_set_run(m: ptr<function, BitMask>, k0: u32, n: u32) {
    var k = k0;
    let end = k0 + n;
    while k < end {
        let w = k / 32u;
        let sh = k % 32u;
        let len = min(end - k, 32u - sh);
        var bits = 0xffffffffu;
        if len != 32u {
            bits = ((1u << len) - 1u) << sh;
        }
        (*m).n_set += countOneBits(bits & ~(*m).words[w]);
        (*m).words[w] |= bits;
        k += len;
    }
}

// bitmask::rect_contains.
fn bitmask_rect_contains(lo: vec2<f32>, hi: vec2<f32>, b: vec2<f32>) -> bool {
    return b.x >= lo.x && b.x <= hi.x && b.y >= lo.y && b.y <= hi.y;
}

// bitmask::quad_contains.
fn bitmask_quad_contains(q: array<vec2<f32>, 4>, flat: bool, b: vec2<f32>) -> bool {
    if flat {
        return bitmask_rect_contains(min(q[0], q[2]), max(q[0], q[2]), b);
    }
    var pos = true;
    var neg = true;
    for (var k = 0u; k < 4u; k++) {
        let e = q[(k + 1u) % 4u] - q[k];
        let d = b - q[k];
        let c = (e.x * d.y) - (e.y * d.x);
        pos = pos && c >= 0.0;
        neg = neg && c <= 0.0;
    }
    return pos || neg;
}
