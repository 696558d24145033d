"""The byte mutator shared by the fuzz tests, the fuzz benchmark and ``fuzz/run.py``.

Structured inputs (JUDP datagrams, bus frames, scenario YAML) are fuzzed best by mutating
valid ones: a few random edits reach deep into the decoder instead of failing at the first byte.
"""

from __future__ import annotations

import random

INTERESTING_BYTES = (0x00, 0xFF, 0x01, 0x10, 0x80)   # boundaries of flags, lengths and counts


def mutate(data: bytes, rng: random.Random) -> bytes:
    """1-4 random edits: flip a bit, overwrite a byte, insert, delete, truncate, extend."""
    buf = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        choice = rng.randrange(6)
        at = rng.randrange(len(buf) + 1)
        if choice == 0 and buf:
            buf[at % len(buf)] ^= 1 << rng.randrange(8)
        elif choice == 1 and buf:
            buf[at % len(buf)] = rng.choice((*INTERESTING_BYTES, rng.randrange(256)))
        elif choice == 2:
            buf[at:at] = rng.randbytes(rng.randint(1, 8))
        elif choice == 3:
            del buf[at : at + rng.randint(1, 8)]
        elif choice == 4:
            del buf[at:]
        else:
            buf += rng.randbytes(rng.randint(1, 16))
    return bytes(buf)
