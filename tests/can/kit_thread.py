"""The emulated PACMod 3 kit on a python-can bus, stepped every 10 ms in a thread of the test
process (the drive runs in the main thread): the in-process end-to-end rig."""

from __future__ import annotations

import contextlib
import math
import threading
import time

from overdrive.runtime.can_edge import CanPort, bus_arrival_s, resolve_can_config
from overdrive.vehicle.pacmod3_kit import Pacmod3Kit

STEP_S = 0.01


class KitThread:
    def __init__(self, params, channel: str, **kit_options) -> None:
        self.kit = Pacmod3Kit(params, **kit_options)
        self.port = CanPort(resolve_can_config(interface="virtual", channel=channel))
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.truths: list = []                 # the kit's ground truth, every step
        self.received: list[tuple[float, object]] = []   # (t, decoded command) in order
        self.start_s = time.monotonic()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> KitThread:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join(5.0)
        self.port.close()

    def _run(self) -> None:
        next_s = time.monotonic()
        wall_minus_mono = time.time() - time.monotonic()   # the virtual bus stamps time.time()
        last_s = 0.0
        while not self.stop.is_set():
            now_s = time.monotonic() - self.start_s
            with self.lock:
                for stamp, frame in self.port.receive(0.0, now_s):
                    # a frame's time is when it was sent (a thread starved by the GIL reads
                    # late frames that were on time), never ahead of now nor behind the last
                    last_s = bus_arrival_s(stamp, wall_minus_mono + self.start_s, now_s,
                                           last_s, math.inf)
                    self.kit.receive(frame, last_s)
                    with contextlib.suppress(ValueError):
                        self.received.append((now_s, self.kit.codec.decode(frame)))
                self.kit.step(now_s)
                self.port.send(self.kit.report_frames(now_s), now_s)
                self.port.traffic()    # not kept
                self.truths.append(self.kit.truth(now_s))
            next_s += STEP_S
            delay = next_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_s = time.monotonic()

    def truth(self):
        with self.lock:
            return self.truths[-1]
