"""HTTP calls to the npfkct server with retries and exponential backoff.

Retried: connection errors and timeouts (the server restarting, a proxy without a replica) and
the server's own "try again later" answers, 503 UNAVAILABLE and 429 RESOURCE_EXHAUSTED with a
Retry-After header, which is respected. Everything else (400, 404, 409 FAILED_PRECONDITION, a
429 without Retry-After: the request's own limit, such as a session's planning budget, which no
retry clears) is an answer and is raised at once."""

import math
import time

import requests

from npfkct_client import ApiError

RETRIED_HTTP = (429, 503)


class RetryPolicy:
    """Up to `attempts` tries; the k-th retry waits base_s * 2**k seconds (at most max_s), or
    the server's Retry-After when it gave one (also capped by max_s)."""

    def __init__(self, attempts=5, base_s=0.2, max_s=5.0):
        if attempts < 1 or base_s < 0 or max_s < 0:
            raise ValueError("retries: attempts >= 1, delays >= 0")
        self.attempts = attempts
        self.base_s = base_s
        self.max_s = max_s

    def delay(self, retry, retry_after=None):
        """Seconds to wait before retry number `retry` (0 for the first retry)."""
        if retry_after is not None and math.isfinite(retry_after):
            return min(max(retry_after, 0.0), self.max_s)
        return min(self.base_s * (2 ** retry), self.max_s)


def retryable(error):
    """Whether an exception from NpfkctClient is worth another try."""
    if isinstance(error, (requests.ConnectionError, requests.Timeout)):
        return True
    if not isinstance(error, ApiError) or error.http_status not in RETRIED_HTTP:
        return False
    return error.http_status != 429 or error.retry_after is not None


def call(fn, policy, sleep=time.sleep, log=None, stop=lambda: False):
    """fn() until it succeeds, raises a non-retryable error, the attempts run out or stop()
    turns true; returns (fn's result, the number of retries it took). `log(msg)` hears each
    retry."""
    retry = 0
    while True:
        try:
            return fn(), retry
        except Exception as e:  # noqa: BLE001 - filtered by retryable() just below
            if not retryable(e) or retry + 1 >= policy.attempts or stop():
                raise
            wait = policy.delay(retry, getattr(e, "retry_after", None))
            if log:
                log(f"{e}; retry {retry + 1}/{policy.attempts - 1} in {wait:.2f} s")
            sleep(wait)
            retry += 1
