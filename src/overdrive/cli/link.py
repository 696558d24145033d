"""``overdrive link-proxy``: inject loss, delay, jitter and cuts on a real UDP link (a JAUS
client and its vehicle), deterministically with a seed (``runtime.link_proxy``)."""

from __future__ import annotations

import contextlib
import math
import signal

import click

from overdrive.bus.link_faults import MAX_DELAY_S, WAYS, LinkFaultSpec, parse_cut
from overdrive.runtime.link_proxy import LinkProxy
from overdrive.runtime.udp import parse_address


def _address(text: str, what: str, *, bind: bool) -> tuple[str, int]:
    try:
        return parse_address(text, what, bind=bind)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None


def _finite(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"a finite number, got {value!r}")
    return value


@click.command("link-proxy")
@click.option("--listen", required=True, metavar="HOST:PORT",
              help="Where the client sends (give it this instead of the vehicle's address).")
@click.option("--to", "to", required=True, metavar="HOST:PORT", help="The vehicle (or xgv-sim).")
@click.option("--from", "upstream", default="0.0.0.0:0", show_default=True, metavar="HOST:PORT",
              help="The proxy's address towards the vehicle (a real XGV answers on port 3794: "
                   "0.0.0.0:3794).")
@click.option("--loss", type=click.FloatRange(0.0, 1.0), default=0.0, show_default=True,
              callback=_finite, help="Fraction of datagrams lost, each independently, both ways.")
@click.option("--delay-ms", type=click.FloatRange(0.0, MAX_DELAY_S * 1e3), default=0.0,
              show_default=True, callback=_finite, help="Added to every datagram, both ways.")
@click.option("--jitter-ms", type=click.FloatRange(0.0, MAX_DELAY_S * 1e3), default=0.0,
              show_default=True, callback=_finite,
              help="Plus a uniform 0..this (more than the gap between datagrams reorders them).")
@click.option("--cut", "cuts", multiple=True, metavar="AT_S:FOR_S",
              help="Nothing passes from AT_S for FOR_S (seconds from the client's first "
                   "datagram); repeatable.")
@click.option("--start-s", type=click.FloatRange(0.0, 86_400.0), default=0.0, show_default=True,
              callback=_finite, help="Loss, delay and jitter apply from this many seconds after "
                                     "the client's first datagram (the link comes up clean).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=0, show_default=True,
              help="Seed of the loss and jitter draws: the same seed, the same decisions.")
@click.option("--way", type=click.Choice(WAYS), default="both", show_default=True,
              help="Every fault on this direction only (to-vehicle: the client's datagrams; "
                   "from-vehicle: the vehicle's); the other passes clean.")
@click.option("--duration-s", type=click.FloatRange(0.0, 86_400.0, min_open=True),
              callback=_finite, help="Stop after this long (default: run until interrupted).")
def link_proxy(listen: str, to: str, upstream: str, loss: float, delay_ms: float,
               jitter_ms: float, cuts: tuple[str, ...], start_s: float, seed: int, way: str,
               duration_s: float | None) -> None:
    """A UDP fault proxy between a JAUS client and its vehicle: loss, delay, jitter, cuts."""
    try:
        spec = LinkFaultSpec(loss=loss, delay_s=delay_ms / 1e3, jitter_s=jitter_ms / 1e3,
                             cuts=tuple(parse_cut(c) for c in cuts), start_s=start_s,
                             seed=seed, way=way)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    listen_at, target, bind = (_address(listen, "--listen", bind=True),
                               _address(to, "--to", bind=False),
                               _address(upstream, "--from", bind=True))
    try:
        proxy = LinkProxy(listen_at, target, spec, bind)
    except OSError as exc:   # a port in use, an address not ours, a name that does not resolve
        raise click.UsageError(f"--listen {listen} / --to {to} / --from {upstream}: "
                               f"{exc.strerror or exc}") from None
    with proxy:
        host, port = proxy.address
        click.echo(f"link-proxy: {host}:{port} -> {target[0]}:{target[1]} (loss {loss}, delay "
                   f"{delay_ms} ms, jitter {jitter_ms} ms, cuts {list(spec.cuts)}, from {start_s} s, seed {seed})",
                   err=True)
        signal.signal(signal.SIGTERM, lambda *_: proxy.stop())   # stop cleanly, print the counts
        with contextlib.suppress(KeyboardInterrupt):
            proxy.serve(duration_s)
        click.echo(f"link-proxy: {proxy.stats()}", err=True)


__all__ = ["link_proxy"]
