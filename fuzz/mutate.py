#!/usr/bin/env python3
"""fuzz/mutate.py OUT_DIR COUNT [ASSETS]: writes COUNT mutated glTF files
built from every .glb in ASSETS (default ../shared/assets), for a
one-off corpus run of the loader's fuzz target that counts its outcomes:

    python3 fuzz/mutate.py build/fuzz/mutants 10000
    GLTF_FUZZ_OUTCOMES=1 build/fuzz/gltf_fuzz -runs=0 build/fuzz/mutants

Seeded (the same files every run). Mutations, one or more per file: byte
flips and random bytes anywhere, truncation, a JSON number replaced by a
hostile one (huge, negative, fractional, exponent), a JSON key's value
replaced by another type, a chunk length or the GLB length rewritten,
bytes repeated. Edits inside the JSON keep the GLB headers consistent so
that the mutant reaches the parser; the others test the container checks.
"""
import os
import random
import re
import struct
import sys

HOSTILE_NUMBERS = [b"-1", b"0", b"1e300", b"-1e300", b"4294967296", b"2147483647", b"2147483648", b"0.5",
                   b"1e-45", b"99999999999999999999", b"-0", b"3.4e38", b"1e39", b"65535", b"65536", b"255"]
HOSTILE_VALUES = [b"null", b"true", b"\"x\"", b"[]", b"{}", b"[1,2,3]", b"-1", b"1e308", b"\"\\u0000\""]


def split_glb(data):
    """(json bytes, bin chunk bytes or None), or None when not a GLB."""
    if len(data) < 20 or data[:4] != b"glTF":
        return None
    jlen = struct.unpack_from("<I", data, 12)[0]
    js = data[20:20 + jlen]
    rest = data[20 + jlen:]
    binc = rest[8:8 + struct.unpack_from("<I", rest, 0)[0]] if len(rest) >= 8 else None
    return js, binc


def join_glb(js, binc):
    js = js + b" " * ((4 - len(js) % 4) % 4)
    out = struct.pack("<I", len(js)) + b"JSON" + js
    if binc is not None:
        binc = binc + b"\0" * ((4 - len(binc) % 4) % 4)
        out += struct.pack("<I", len(binc)) + b"BIN\0" + binc
    return b"glTF" + struct.pack("<II", 2, 12 + len(out)) + out


def mutate_json(rng, js):
    numbers = [m.span() for m in re.finditer(rb"-?\d+(\.\d+)?([eE][-+]?\d+)?", js)]
    keys = [m.span(1) for m in re.finditer(rb"\"[A-Za-z_]+\"\s*:\s*([^,\]}]+)", js)]
    for _ in range(rng.randint(1, 4)):
        if numbers and rng.random() < 0.7:
            a, b = rng.choice(numbers)
            js = js[:a] + rng.choice(HOSTILE_NUMBERS) + js[b:]
        elif keys:
            a, b = rng.choice(keys)
            js = js[:a] + rng.choice(HOSTILE_VALUES) + js[b:]
        numbers = [m.span() for m in re.finditer(rb"-?\d+(\.\d+)?([eE][-+]?\d+)?", js)]
        keys = [m.span(1) for m in re.finditer(rb"\"[A-Za-z_]+\"\s*:\s*([^,\]}]+)", js)]
    return js


def mutate_bytes(rng, data):
    data = bytearray(data)
    kind = rng.randrange(5)
    if kind == 0:  # flips
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
    elif kind == 1:  # random bytes
        for _ in range(rng.randint(1, 16)):
            data[rng.randrange(len(data))] = rng.randrange(256)
    elif kind == 2:  # truncation
        del data[rng.randrange(1, len(data)):]
    elif kind == 3:  # a header length rewritten
        at = rng.choice([8, 12, 16]) if len(data) >= 20 else 0
        struct.pack_into("<I", data, at, rng.choice([0, 1, 7, 0x7FFFFFFF, 0xFFFFFFFF, len(data) * 2]))
    else:  # bytes repeated
        a = rng.randrange(len(data))
        b = min(len(data), a + rng.randint(1, 4096))
        data[a:a] = data[a:b] * rng.randint(1, 8)
    return bytes(data)


def main():
    out, count = sys.argv[1], int(sys.argv[2])
    assets = sys.argv[3] if len(sys.argv) > 3 else "../shared/assets"
    seeds = [open(os.path.join(assets, f), "rb").read() for f in sorted(os.listdir(assets)) if f.endswith(".glb")]
    os.makedirs(out, exist_ok=True)
    rng = random.Random(1)
    for k in range(count):
        data = rng.choice(seeds)
        parts = split_glb(data)
        if parts and rng.random() < 0.6:
            js, binc = parts
            data = join_glb(mutate_json(rng, js), binc)
            if rng.random() < 0.2:
                data = mutate_bytes(rng, data)
        else:
            data = mutate_bytes(rng, data)
        with open(os.path.join(out, "m%05d.glb" % k), "wb") as f:
            f.write(data)


if __name__ == "__main__":
    main()
