#!/usr/bin/env python3
"""Issue 15, scale-out: a model of one solve's parallel efficiency on K = 2 .. 1024 processes.

    PYTHONPATH=build/python python3 docs/figures/mpi/model.py SCENE --photons 1e7 --scale 1 100

It solves SCENE once on one thread (the flatland module) to learn the sizes of its rounds and the
time per photon, then models K processes, each a single core:

    T_K = sum over rounds of [ s_r  +  ceil(b_r / K) * 4096 * t  +  A(K, m) ]

where b_r is the round's number of 4096-photon batches (the most any process shoots decides the
round), t the time per photon (the slope of a least-squares fit of the measured round times T_r
against the round sizes n_r) and s_r = T_r - n_r t the round's serial time (the estimator, the level
choice, the next round's sampler: every process does it), and A the time of an allreduce of the round's message of m
bytes (8 per storage coefficient and channel, twice with auto storage, and 12 counters: what
`flatland solve` under mpirun prints as "summed per round"): 2 ceil(log2 K) alpha + 2 (K-1)/K m / beta
(reduce-scatter then allgather). The interconnect assumed is 100 Gb/s InfiniBand: alpha = 2 us per
step, beta = 12 GB/s. Efficiency is T_1 / (K T_K) for the shooting; the set-up, which every process
repeats, is left out (its time is printed) and --scale multiplies every round (a budget --scale
times larger has rounds about that much larger: the schedule shares the budget in proportion to
the power still to be shot, down to the floor of 256 photons a round); the message is then that of
a solver set up for the larger budget (auto storage refines with the budget).
"""
import argparse
import math
import time

import flatland

BATCH = 4096


def allreduce(k, message, alpha, beta):
    if k == 1:
        return 0.0
    return 2 * math.ceil(math.log2(k)) * alpha + 2 * (k - 1) / k * message / beta


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--photons", type=float, default=1e7)
    parser.add_argument("--tolerance", type=float, default=1e-9)
    parser.add_argument("--scale", type=float, nargs="*", default=[1.0, 100.0])
    parser.add_argument("--alpha", type=float, default=2e-6)
    parser.add_argument("--beta", type=float, default=12e9)
    args = parser.parse_args()

    scene = flatland.Scene.load(args.scene)
    start = time.perf_counter()
    solver = flatland.Solver(scene, photons=int(args.photons), tolerance=args.tolerance, threads=1)
    setup = time.perf_counter() - start
    rounds, times = [], []
    while solver.step_round():
        rounds.append(solver.stats["photons"] - sum(rounds))
        times.append(solver.stats["seconds"] - sum(times))
    # T_r = s + n_r t by least squares.
    n_mean, t_mean = sum(rounds) / len(rounds), sum(times) / len(times)
    t = (sum((n - n_mean) * (x - t_mean) for n, x in zip(rounds, times))
         / sum((n - n_mean) ** 2 for n in rounds))
    serial = [max(0.0, x - n * t) for n, x in zip(rounds, times)]

    def message(photons):
        # Auto storage (the default) sends the deposits of the even and the odd photons apart.
        coefficients = flatland.Solver(scene, photons=int(photons), tolerance=args.tolerance).stats["coefficients"]
        return (coefficients * scene.channels * 2 + 12) * 8

    print(f"{args.scene}: {len(rounds)} rounds, {solver.stats['photons']:.3g} photons, "
          f"{t * 1e9:.0f} ns per photon, {sum(serial) / len(serial) * 1e3:.2f} ms serial per round (most {max(serial) * 1e3:.1f} ms), set-up {setup:.2f} s, {message(args.photons):.3g} bytes per round; "
          f"largest round {max(rounds)}, rounds under one batch {sum(r <= BATCH for r in rounds)}")
    ks = [1, 2, 8, 32, 128, 512, 1024]
    print("| photons | bytes per round | " + " | ".join(f"K = {k}" for k in ks[1:]) + " |")
    print("|---|---|" + "---|" * (len(ks) - 1))
    for scale in args.scale:
        sizes = [max(256, round(r * scale)) for r in rounds]
        m = message(args.photons * scale)
        # The serial work is over the storage coefficients: it grows with the message.
        grow = m / message(args.photons)
        one = sum(sizes) * t + sum(serial) * grow
        cells = []
        for k in ks[1:]:
            shoot = sum(math.ceil(math.ceil(n / BATCH) / k) * min(n, BATCH) * t for n in sizes)
            total = shoot + sum(serial) * grow + len(sizes) * allreduce(k, m, args.alpha, args.beta)
            cells.append(f"{one / (k * total):.2f}")
        print(f"| {sum(sizes):.2g} | {m:.3g} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
