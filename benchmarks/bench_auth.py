"""What checking a bearer token costs an API request, with 1,000 users (prints JSON).

* ``authenticate_us``: :meth:`Users.authenticate` with a valid token and with a wrong one, per call (a SHA-256 and
  one indexed query of the records' database);
* ``first_after_change_ms``: the first call after another process (another engine) rotated a token;
* ``add_ms``: adding a user to 1,000 others (the CLI's side: lock, read, rewrite, fsync, rename);
* ``login_cookie_us``: checking the web page's login cookie (HMAC, expiry, the user's current token binding),
  and issuing one.

The data directory is a fresh temporary folder (``--dir`` to put it on another file system).

    python -m benchmarks.bench_auth [--users 1000] [--calls 20000] [--dir DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time

from benchmarks.common import machine, median_ms
from curvefm.access import TOKEN_PREFIX, Users, signing_key
from curvefm.records import open_database
from curvefm.service.login import LoginCookies


def elapsed_ns(fn) -> int:
    start = time.perf_counter_ns()
    fn()
    return time.perf_counter_ns() - start


def per_call_us(fn, calls: int) -> dict:
    times = sorted(elapsed_ns(fn) for _ in range(calls))
    return {
        "p50": round(times[len(times) // 2] / 1e3, 2),
        "p99": round(times[int(len(times) * 0.99)] / 1e3, 2),
        "mean": round(statistics.fmean(times) / 1e3, 2),
    }


def first_after_change_ms(api: Users, cli: Users, token: str, repeat: int) -> float:
    def change_then_authenticate() -> int:
        cli.rotate("user0")  # not timed
        return elapsed_ns(lambda: api.authenticate(token))

    return round(statistics.median(change_then_authenticate() for _ in range(repeat)) / 1e6, 3)


def main() -> None:
    options = argparse.ArgumentParser(description=__doc__)
    options.add_argument("--users", type=int, default=1000)
    options.add_argument("--calls", type=int, default=20000)
    options.add_argument("--dir", help="parent folder of the temporary data directory")
    args = options.parse_args()
    with tempfile.TemporaryDirectory(dir=args.dir) as data:
        # two instances on two engines: the CLI's and an API process's
        cli, api = Users(open_database(data)), Users(open_database(data))
        tokens = [cli.add(f"user{i}") for i in range(args.users)]
        token = tokens[len(tokens) // 2]
        assert api.authenticate(token) is not None
        wrong = TOKEN_PREFIX + "x" * 43
        extra = (f"extra{i}" for i in range(20))
        cookies = LoginCookies(signing_key(data), api, ttl_s=3600)
        user = api.authenticate(token)
        cookie = cookies.issue(user)
        assert cookies.verify(cookie) == user
        print(
            json.dumps(
                {
                    "users": args.users,
                    "calls": args.calls,
                    "authenticate_us": {
                        "valid": per_call_us(lambda: api.authenticate(token), args.calls),
                        "wrong": per_call_us(lambda: api.authenticate(wrong), args.calls),
                    },
                    "login_cookie_us": {
                        "verify": per_call_us(lambda: cookies.verify(cookie), args.calls),
                        "issue": per_call_us(lambda: cookies.issue(user), args.calls),
                    },
                    "first_after_change_ms": first_after_change_ms(api, cli, token, 20),
                    "add_ms": round(median_ms(lambda: cli.add(next(extra)), 20), 2),
                    "file_bytes": api.path.stat().st_size,
                    "machine": machine(),
                },
                indent=2,
            )
        )


if __name__ == "__main__":
    main()
