"""GET /metrics counts every response with the status it was sent with: a PNG belief, /metrics
itself, /healthz and JSON routes, successes and errors alike (never code="-1", httplib's "not
set yet")."""

import re

import requests

from conftest import world_of


def counts(url):
    """{(method, route, code): count} of npfkct_http_requests_total."""
    text = requests.get(url + "/metrics", timeout=10).text
    out = {}
    for m in re.finditer(r'^npfkct_http_requests_total\{method="([^"]*)",route="([^"]*)",'
                         r'code="([^"]*)"\} (\d+)$', text, re.M):
        out[(m.group(1), m.group(2), m.group(3))] = int(m.group(4))
    assert out, text
    return out


def test_every_response_is_counted_with_its_status(server):
    url = server.url
    session = requests.post(url + "/v1/sessions", json={"world": world_of("hidden1"), "seed": 3},
                            timeout=30).json()
    png = requests.get(url + f"/v1/sessions/{session['id']}/belief", params={"format": "png"},
                       timeout=30)
    assert png.status_code == 200 and png.content.startswith(b"\x89PNG")
    assert requests.get(url + f"/v1/sessions/{session['id']}/belief", timeout=30).ok
    assert requests.get(url + "/metrics", timeout=10).status_code == 200
    assert requests.get(url + "/healthz", timeout=10).status_code == 200
    assert requests.get(url + "/v1/sessions/" + "0" * 32, timeout=10).status_code == 404

    c = counts(url)  # itself counted before it is written: the /metrics above at least
    assert c.get(("GET", "/v1/sessions/{id}/belief", "200")) == 2, c
    assert c.get(("GET", "/metrics", "200"), 0) >= 1, c
    assert c.get(("GET", "/healthz", "200")) == 1, c
    assert c.get(("POST", "/v1/sessions", "200")) == 1, c
    assert c.get(("GET", "/v1/sessions/{id}", "404")) == 1, c
    assert not [k for k in c if not re.fullmatch(r"[1-5]\d\d", k[2])], c

    before = counts(url)[("GET", "/metrics", "200")]
    assert counts(url)[("GET", "/metrics", "200")] == before + 1
