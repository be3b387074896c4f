"""The npfkct HTTP/JSON API as typed Python calls."""

from __future__ import annotations

import base64
import concurrent.futures
import dataclasses
import email.utils
import json
import math
import os
import socket
import struct
import threading
import time
from typing import Any, Callable, Dict, Iterable, List, Optional, Sequence, Tuple

import requests
import requests.adapters
import urllib3
import urllib3.connection
import urllib3.poolmanager


class ApiError(Exception):
    """An error response: HTTP status, canonical status name, message, the offending fields
    (`violations`: (field, description) pairs, `field`: the first one) and, for 429, the
    seconds to wait before retrying (`retry_after`)."""

    def __init__(self, http_status: int, status: str, message: str, field: str = "",
                 violations: Optional[List[Tuple[str, str]]] = None,
                 retry_after: Optional[float] = None):
        super().__init__(f"{status} ({http_status}): {message}")
        self.http_status = http_status
        self.status = status
        self.message = message
        self.field = field
        self.violations = violations or []
        self.retry_after = retry_after


@dataclasses.dataclass
class RobotConfig:
    """Base pose (x, y, yaw), lift height, head pan and tilt (positive tilt looks down)."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    lift: float = 0.0
    pan: float = 0.0
    tilt: float = 0.0

    @classmethod
    def from_json(cls, j: Dict[str, Any]) -> "RobotConfig":
        return cls(**{k: float(j.get(k, 0.0)) for k in ("x", "y", "yaw", "lift", "pan", "tilt")})

    def to_json(self) -> Dict[str, float]:
        return dataclasses.asdict(self)


@dataclasses.dataclass
class Box:
    """An upright oriented box: center, yaw about z, full extents."""

    center: List[float]
    size: List[float]
    yaw: float = 0.0

    @classmethod
    def from_json(cls, j: Dict[str, Any]) -> "Box":
        return cls(center=list(j["center"]), size=list(j["size"]), yaw=float(j.get("yaw", 0.0)))

    def to_json(self) -> Dict[str, Any]:
        return {"center": list(self.center), "yaw": self.yaw, "size": list(self.size)}


@dataclasses.dataclass
class Face:
    """Detection of one face grid (box corner 0..7): probability it shows the target."""

    corner: int
    score: float


@dataclasses.dataclass
class Detection:
    """An object the robot saw, with a stable id across steps: per-face scores (`faces`), or
    one `score` for the whole box as a 3D detector gives it (the server gives it to the faces
    the camera sees)."""

    id: str
    box: Box
    moveability: float = 1.0
    faces: List[Face] = dataclasses.field(default_factory=list)
    score: Optional[float] = None

    def to_json(self) -> Dict[str, Any]:
        out = {"id": self.id, "box": self.box.to_json(), "moveability": self.moveability}
        if self.score is not None:
            out["score"] = self.score
        else:
            out["faces"] = [dataclasses.asdict(f) for f in self.faces]
        return out


@dataclasses.dataclass
class Action:
    """MOVE to a configuration, or DECLARE_TARGET / DECLARE_OBSTACLE / REMOVE an object."""

    type: str
    configuration: Optional[RobotConfig] = None
    object_id: Optional[str] = None
    object_box: Optional[Box] = None  # where the object is, as the robot last saw it

    @classmethod
    def from_json(cls, j: Dict[str, Any]) -> "Action":
        if j["type"] == "MOVE":
            return cls("MOVE", configuration=RobotConfig.from_json(j["configuration"]))
        box = j.get("objectBox")
        return cls(j["type"], object_id=j["objectId"],
                   object_box=Box.from_json(box) if box else None)

    def to_json(self) -> Dict[str, Any]:
        if self.type == "MOVE":
            return {"type": "MOVE", "configuration": self.configuration.to_json()}
        out: Dict[str, Any] = {"type": self.type, "objectId": self.object_id}
        if self.object_box is not None:
            out["objectBox"] = self.object_box.to_json()
        return out


@dataclasses.dataclass
class PointCloud:
    """Raw points for the server's perception: little-endian float32 x, y, z (and, with fields
    "xyzrgb", a fourth float packing 0x00RRGGBB as PCL does), in the camera's optical frame
    ("camera": x right, y down, z forward) or the map frame ("map")."""

    data: bytes
    fields: str = "xyz"
    frame: str = "camera"

    @classmethod
    def from_depth(cls, depth: Iterable[Sequence[float]], camera: Dict[str, float]) -> "PointCloud":
        """The camera-frame cloud of a depth image (rows of metres; 0 or NaN where nothing was
        seen; a numpy array will do) with the pinhole intrinsics {fx, fy, cx, cy}."""
        fx, fy, cx, cy = camera["fx"], camera["fy"], camera["cx"], camera["cy"]
        out = bytearray()
        for v, row in enumerate(depth):
            for u, z in enumerate(row):
                z = float(z)
                if z > 0.0:  # NaN compares false
                    out += struct.pack("<fff", (u + 0.5 - cx) / fx * z, (v + 0.5 - cy) / fy * z, z)
        return cls(bytes(out), "xyz", "camera")

    @classmethod
    def from_points(cls, points: Iterable[Sequence[float]], frame: str = "camera",
                    colors: Optional[Iterable[Sequence[int]]] = None) -> "PointCloud":
        """Packs (x, y, z) tuples, with optional (r, g, b) colours; NaN points are dropped."""
        out = bytearray()
        if colors is None:
            for p in points:
                if all(v == v for v in p[:3]):
                    out += struct.pack("<fff", p[0], p[1], p[2])
            return cls(bytes(out), "xyz", frame)
        for p, c in zip(points, colors):
            if all(v == v for v in p[:3]):
                out += struct.pack("<fffI", p[0], p[1], p[2], (c[0] << 16) | (c[1] << 8) | c[2])
        return cls(bytes(out), "xyzrgb", frame)

    def to_json(self) -> Dict[str, Any]:
        return {"frame": self.frame, "fields": self.fields,
                "data": base64.b64encode(self.data).decode()}


@dataclasses.dataclass
class ImageBox:
    """A box of the robot's own detector in the camera image (pixels: left x, top y, width,
    height) with `score`, the probability that it shows the target: a YOLO-style detection of
    the target's class. Sent with the depth (a PointCloud), the server gives each box to the
    object whose pixels it holds and scores the objects with it."""

    x: float
    y: float
    width: float
    height: float
    score: float

    @classmethod
    def from_xyxy(cls, x1: float, y1: float, x2: float, y2: float, score: float) -> "ImageBox":
        """From corner coordinates, as YOLO-style detectors give them (xyxy)."""
        return cls(float(x1), float(y1), float(x2) - float(x1), float(y2) - float(y1),
                   float(score))

    def to_json(self) -> Dict[str, Any]:
        return {"x": self.x, "y": self.y, "width": self.width, "height": self.height,
                "score": self.score}


@dataclasses.dataclass
class Session:
    """A session resource, as a reply described it. A session that a client made or fetched is
    also a handle on the server's session: plan, observe and delete call the server, and `with`
    deletes it on exit (`with client.create_session(world) as s: ...`)."""

    id: str
    name: str
    state: str
    step: int
    robot: RobotConfig
    object_count: int
    pending_action_id: Optional[str]
    raw: Dict[str, Any]
    client: Optional["NpfkctClient"] = dataclasses.field(default=None, repr=False, compare=False)

    @classmethod
    def from_json(cls, j: Dict[str, Any], client: Optional["NpfkctClient"] = None) -> "Session":
        pending = j.get("pendingAction")
        return cls(
            id=j["id"],
            name=j["name"],
            state=j["state"],
            step=j["step"],
            robot=RobotConfig.from_json(j["robot"]),
            object_count=j["objectCount"],
            pending_action_id=pending["actionId"] if pending else None,
            raw=j,
            client=client,
        )

    @property
    def done(self) -> bool:
        """Whether the target was removed (the episode is over)."""
        return self.state == "DONE"

    def _client(self) -> "NpfkctClient":
        if self.client is None:
            raise ValueError("this Session was read from JSON without a client: "
                             "use NpfkctClient.get_session")
        return self.client

    def plan(self, time_ms: Optional[float] = None, simulations: Optional[int] = None,
             cpu_ms: Optional[float] = None) -> "Plan":
        """NpfkctClient.plan on this session."""
        return self._client().plan(self.id, time_ms=time_ms, simulations=simulations,
                                   cpu_ms=cpu_ms)

    def plan_async(self, time_ms: Optional[float] = None, simulations: Optional[int] = None,
                   cpu_ms: Optional[float] = None) -> "PlanFuture":
        """NpfkctClient.plan_async on this session."""
        return self._client().plan_async(self.id, time_ms=time_ms, simulations=simulations,
                                         cpu_ms=cpu_ms)

    def observe(self, action_id: str, **kwargs: Any) -> "Observation":
        """NpfkctClient.observe on this session (the same keyword arguments)."""
        return self._client().observe(self.id, action_id, **kwargs)

    def refresh(self) -> "Session":
        """The session as the server holds it now."""
        return self._client().get_session(self.id)

    def belief(self) -> Dict[str, Any]:
        return self._client().belief(self.id)

    def belief_png(self) -> bytes:
        return self._client().belief_png(self.id)

    def delete(self) -> None:
        """Deletes the session (a plan running on it stops); deleting it twice is no error."""
        try:
            self._client().delete_session(self.id)
        except ApiError as e:
            if e.status != "NOT_FOUND":
                raise

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.delete()


@dataclasses.dataclass
class Stats:
    """What a plan's search did (schemas/common.schema.json, Stats)."""

    simulations: int
    elapsed_ms: float
    cpu_ms: Optional[float]
    tree_nodes: int
    max_depth: int
    root_actions: int
    root_visits: int
    reused_visits: int  # visits of the previous step's tree that this search started from
    budget_exhausted: Optional[bool]  # whether the budget, not the tree, ended the search
    raw: Dict[str, Any]

    @classmethod
    def from_json(cls, j: Dict[str, Any]) -> "Stats":
        return cls(simulations=j["simulations"], elapsed_ms=j["elapsedMs"],
                   cpu_ms=j.get("cpuMs"), tree_nodes=j["treeNodes"], max_depth=j["maxDepth"],
                   root_actions=j["rootActions"], root_visits=j["rootVisits"],
                   reused_visits=j["reusedVisits"], budget_exhausted=j.get("budgetExhausted"),
                   raw=j)

    def __getitem__(self, key: str) -> Any:
        """The reply's own field by its JSON name (stats["simulations"])."""
        return self.raw[key]


@dataclasses.dataclass
class Plan:
    """The answer of :plan."""

    action_id: str
    action: Action
    expected_value: float
    stats: Stats
    session: Session
    budget: Dict[str, Any] = dataclasses.field(default_factory=dict)  # as the planner used it

    @classmethod
    def from_json(cls, j: Dict[str, Any], client: Optional["NpfkctClient"] = None) -> "Plan":
        return cls(
            action_id=j["actionId"],
            action=Action.from_json(j["action"]),
            expected_value=j["expectedValue"],
            stats=Stats.from_json(j["stats"]),
            session=Session.from_json(j["session"], client),
            budget=j.get("budget", {}),
        )

    @property
    def value(self) -> float:
        """The search's expected discounted reward of the action."""
        return self.expected_value


@dataclasses.dataclass
class Observation:
    """The answer of :observe."""

    done: bool
    reward: float
    session: Session
    perception: Optional[Dict[str, Any]] = None  # what perception made of raw data


def _retry_after(value: Optional[str]) -> Optional[float]:
    """Retry-After as seconds (RFC 9110 10.2.3: a number of seconds or an HTTP date); None when
    absent or unreadable."""
    if not value:
        return None
    try:
        seconds = float(value)
    except ValueError:
        try:
            when = email.utils.parsedate_to_datetime(value)
        except (TypeError, ValueError, IndexError):
            return None
        if when is None or when.tzinfo is None:
            return None
        seconds = when.timestamp() - time.time()
    # Finite, and at most a day: time.sleep refuses 1e308.
    return min(max(seconds, 0.0), 86400.0) if math.isfinite(seconds) else None


def _strings(j: Any, *keys: str) -> List[str]:
    """The members `keys` of `j` as strings ("" where `j` is no object or a member no string)."""
    return [j.get(k) if isinstance(j, dict) and isinstance(j.get(k), str) else "" for k in keys]


def _typed(convert: Callable[[Any], Any], reply: Any) -> Any:
    """convert(reply), an ApiError (DATA_LOSS) where the reply is not what the API describes."""
    try:
        return convert(reply)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, OverflowError) as e:
        raise ApiError(200, "DATA_LOSS",
                       f"the server's reply is not what the API describes: {e!r}") from None


class _Call:
    """One call's deadline: when it expires, the socket the call waits on is shut (a read
    blocked in another thread wakes only then; close() alone leaves it waiting)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.sock = None
        self.expired = False
        self.cancelled = False  # expired by PlanFuture.cancel, not by the deadline

    def watch(self, sock):
        with self.lock:
            self.sock = sock
            expired = self.expired
        if expired:
            _shut(sock)

    def expire(self):
        with self.lock:
            self.expired = True
            sock = self.sock
        _shut(sock)


def _shut(sock):
    try:
        if sock is not None:
            sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass


_WATCHED = threading.local()  # the calling thread's _Call


class _WatchedConnection:
    """Hands its socket to the calling thread's _Call before it waits for the reply's head (a
    server could send that a byte at a time, or 1xx replies without end)."""

    def getresponse(self, *args, **kwargs):
        call = getattr(_WATCHED, "call", None)
        if call is not None:
            call.watch(self.sock)
        return super().getresponse(*args, **kwargs)


class _HTTPConnection(_WatchedConnection, urllib3.connection.HTTPConnection):
    pass


class _HTTPSConnection(_WatchedConnection, urllib3.connection.HTTPSConnection):
    pass


class _HTTPPool(urllib3.HTTPConnectionPool):
    ConnectionCls = _HTTPConnection


class _HTTPSPool(urllib3.HTTPSConnectionPool):
    ConnectionCls = _HTTPSConnection


def _watched(manager):
    """`manager` with the watched pools (a SOCKS proxy's own pools are left as they are)."""
    if manager.pool_classes_by_scheme is urllib3.poolmanager.pool_classes_by_scheme:
        manager.pool_classes_by_scheme = {"http": _HTTPPool, "https": _HTTPSPool}
    return manager


class _WatchedAdapter(requests.adapters.HTTPAdapter):
    """Direct connections and those through an HTTP proxy, both watched."""

    def init_poolmanager(self, *args, **kwargs):
        super().init_poolmanager(*args, **kwargs)
        _watched(self.poolmanager)

    def proxy_manager_for(self, *args, **kwargs):
        return _watched(super().proxy_manager_for(*args, **kwargs))


class PlanFuture:
    """A plan running in the background (NpfkctClient.plan_async). cancel() hangs up on it: the
    server stops the search within milliseconds, and the session has no pending action, so it may
    plan again (a plan right after a cancel may be answered ABORTED while the server notices;
    retry it)."""

    def __init__(self, run: Callable[["_Call"], "Plan"]):
        self._call = _Call()
        self._future: concurrent.futures.Future = concurrent.futures.Future()
        self._thread = threading.Thread(target=self._run, args=(run,), daemon=True)
        self._thread.start()

    def _run(self, run: Callable[["_Call"], "Plan"]) -> None:
        if not self._future.set_running_or_notify_cancel():
            return
        try:
            plan = run(self._call)
        except BaseException as e:  # handed to result()
            if self._call.cancelled:
                e = concurrent.futures.CancelledError()
            self._future.set_exception(e)
        else:
            self._future.set_result(plan)

    def cancel(self) -> bool:
        """Stops the plan (the connection is closed, and the server stops with it); False when it
        had already finished."""
        if self._future.done():
            return False
        with self._call.lock:
            self._call.cancelled = True
        self._call.expire()
        return True

    def cancelled(self) -> bool:
        return self._future.done() and isinstance(self._future.exception(),
                                                  concurrent.futures.CancelledError)

    def done(self) -> bool:
        return self._future.done()

    def result(self, timeout: Optional[float] = None) -> "Plan":
        """The plan; raises ApiError as plan() does, concurrent.futures.CancelledError after a
        cancel, TimeoutError when it is not done within `timeout` seconds."""
        return self._future.result(timeout)

    def exception(self, timeout: Optional[float] = None) -> Optional[BaseException]:
        return self._future.exception(timeout)

    def add_done_callback(self, fn: Callable[["PlanFuture"], Any]) -> None:
        self._future.add_done_callback(lambda _: fn(self))


class NpfkctClient:
    """Client of one npfkct server. Every call raises ApiError on an error response, and on a
    reply larger than `max_reply_bytes`, not JSON or nested deeper than Python's parser goes;
    `timeout` bounds the whole call from the request on (a server sending a byte at a time is
    cut off). The server's URL and API key default to $NPFKCT_SERVER (else
    http://127.0.0.1:8080) and $NPFKCT_API_KEY. A client may be shared by threads."""

    def __init__(self, base_url: Optional[str] = None, api_key: Optional[str] = None,
                 timeout: float = 120.0, max_reply_bytes: int = 64 << 20):
        if not (isinstance(timeout, (int, float)) and 0 < timeout <= 1e6):
            raise ValueError("timeout: seconds, > 0 and <= 1e6")
        if base_url is None:
            base_url = os.environ.get("NPFKCT_SERVER") or "http://127.0.0.1:8080"
        if api_key is None:
            api_key = os.environ.get("NPFKCT_API_KEY") or None
        self.base_url = base_url.rstrip("/")
        self.timeout = timeout
        self.max_reply_bytes = max_reply_bytes
        self._http = requests.Session()
        for scheme in ("http://", "https://"):
            self._http.mount(scheme, _WatchedAdapter())
        self._http.headers["Accept-Encoding"] = "identity"
        if api_key:
            self._http.headers["Authorization"] = f"Bearer {api_key}"

    # -- transport --

    def _read(self, response: requests.Response, call: "_Call") -> bytes:
        """The reply's body, up to max_reply_bytes (the call's deadline cuts it off)."""
        chunks, size = [], 0
        try:
            # The server never compresses (identity is asked for): a compressed reply would be
            # inflated whole, read by read, before its size could be counted.
            coding = response.headers.get("Content-Encoding", "identity").strip().lower()
            if coding not in ("", "identity"):
                raise ApiError(response.status_code, "DATA_LOSS",
                               f"the reply is compressed ({coding[:40]}), which was not asked for")
            for chunk in response.iter_content(65536):
                size += len(chunk)
                if size > self.max_reply_bytes:
                    raise ApiError(response.status_code, "RESOURCE_EXHAUSTED",
                                   f"the reply is larger than {self.max_reply_bytes} bytes")
                chunks.append(chunk)
        except (requests.RequestException, OSError, AttributeError, ValueError) as e:
            if isinstance(e, requests.Timeout):  # a wait past `timeout`, before the deadline
                raise ApiError(response.status_code, "DEADLINE_EXCEEDED",
                               f"the reply did not arrive whole within {self.timeout} s") from None
            if not call.expired:
                raise
        finally:
            response.close()
        if call.expired:
            raise ApiError(response.status_code, "DEADLINE_EXCEEDED",
                           f"the reply did not arrive whole within {self.timeout} s")
        return b"".join(chunks)

    @staticmethod
    def _json(status: int, content: bytes) -> Any:
        try:
            return json.loads(content)
        except RecursionError:
            raise ApiError(status, "DATA_LOSS", "the reply nests too deeply") from None

    def _call(self, method: str, path: str, body: Optional[Dict[str, Any]] = None,
              params: Optional[Dict[str, Any]] = None, raw: bool = False,
              call: Optional[_Call] = None):
        call = call or _Call()
        _WATCHED.call = call
        timer = threading.Timer(self.timeout, call.expire)
        timer.daemon = True
        timer.start()
        try:
            try:
                # No redirects: the server never sends one, and requests would read a
                # redirect's body whole, past the reply cap.
                response = self._http.request(
                    method, self.base_url + path, params=params, timeout=self.timeout,
                    stream=True, data=None if body is None else json.dumps(body),
                    headers={"Content-Type": "application/json"} if body is not None else None,
                    allow_redirects=False)
            except (requests.RequestException, OSError) as e:
                if not call.expired and not isinstance(e, requests.Timeout):
                    raise
                if call.cancelled:
                    raise ApiError(0, "CANCELLED", "the call was cancelled") from None
                raise ApiError(0, "DEADLINE_EXCEEDED",
                               f"the server did not answer within {self.timeout} s") from None
            if 300 <= response.status_code < 400:
                response.close()
                raise ApiError(response.status_code, "UNKNOWN",
                               "the server redirected the call, which it never does")
            content = self._read(response, call)
        finally:
            timer.cancel()
            _WATCHED.call = None
        if response.status_code >= 400:
            try:
                err = self._json(response.status_code, content)["error"]
            except (ValueError, KeyError, TypeError, ApiError):
                err = None
            if not isinstance(err, dict):
                raise ApiError(response.status_code, "UNKNOWN",
                               content[:4096].decode("utf-8", "replace"))
            details = err.get("details")
            violations = [tuple(_strings(v, "field", "description"))
                          for detail in (details if isinstance(details, list) else [])
                          if isinstance(detail, dict)
                          and isinstance(detail.get("fieldViolations"), list)
                          for v in detail["fieldViolations"] if isinstance(v, dict)]
            status, message = _strings(err, "status", "message")
            raise ApiError(response.status_code, status or "UNKNOWN", message,
                           violations[0][0] if violations else "", violations,
                           _retry_after(response.headers.get("Retry-After")))
        if raw:
            return content
        try:
            return self._json(response.status_code, content)
        except ValueError:
            raise ApiError(response.status_code, "DATA_LOSS", "the reply is not JSON") from None

    # -- API --

    def health(self) -> Dict[str, Any]:
        return self._call("GET", "/healthz")

    def metrics(self) -> str:
        return self._call("GET", "/metrics", raw=True).decode("utf-8", "replace")

    def create_session(self, world: Dict[str, Any], planner: str = "npfkct",
                       particles: Optional[int] = None,
                       options: Optional[Dict[str, Any]] = None, seed: Optional[int] = None,
                       display_name: Optional[str] = None,
                       ttl_seconds: Optional[float] = None,
                       target_description: Optional[str] = None,
                       target_photos: Optional[List[bytes]] = None,
                       model: Optional[str] = None) -> Session:
        """Creates a session; `target_photos` are PNG or JPEG files' bytes of the target, for
        the server's perception to match camera images against; `model` names a neural filter
        model of the server's model folder (e.g. "filter.pt", npfkct only)."""
        body: Dict[str, Any] = {"world": world, "planner": {"name": planner}}
        if model:
            body["planner"]["model"] = model
        if particles is not None:
            body["planner"]["particles"] = particles
        if options:
            body["planner"]["options"] = options
        if seed is not None:
            body["seed"] = seed
        if display_name:
            body["displayName"] = display_name
        if ttl_seconds is not None:
            body["ttlSeconds"] = ttl_seconds
        if target_description or target_photos:
            body["target"] = {}
            if target_description:
                body["target"]["description"] = target_description
            if target_photos:
                body["target"]["photos"] = [base64.b64encode(p).decode() for p in target_photos]
        return _typed(lambda j: Session.from_json(j, self), self._call("POST", "/v1/sessions", body))

    def get_session(self, session_id: str) -> Session:
        return _typed(lambda j: Session.from_json(j, self),
                      self._call("GET", f"/v1/sessions/{session_id}"))

    def list_sessions(self, page_size: int = 50) -> List[Session]:
        sessions: List[Session] = []
        token = ""
        seen = set()
        # A server holds at most --max-sessions (or, in a fleet, --max-stored-sessions) sessions:
        # pages beyond 10,000, or a token given twice, are a server going round in circles.
        for _ in range(10000):
            params: Dict[str, Any] = {"pageSize": page_size}
            if token:
                params["pageToken"] = token
            page = self._call("GET", "/v1/sessions", params=params)
            sessions += _typed(lambda p: [Session.from_json(s, self) for s in p["sessions"]], page)
            token = _typed(lambda p: p.get("nextPageToken", ""), page)
            if not token:
                return sessions
            if not isinstance(token, str) or token in seen:
                raise ApiError(200, "DATA_LOSS", "the server's page tokens go round in circles")
            seen.add(token)
        raise ApiError(200, "DATA_LOSS", "the server's session list has more than 10,000 pages")

    def delete_session(self, session_id: str) -> None:
        self._call("DELETE", f"/v1/sessions/{session_id}")

    def plan(self, session_id: str, time_ms: Optional[float] = None,
             simulations: Optional[int] = None, cpu_ms: Optional[float] = None) -> Plan:
        """Plans within a budget of wall-clock milliseconds, CPU milliseconds of the planning
        thread and/or simulations (none: the server's default)."""
        return self._plan(session_id, time_ms, simulations, cpu_ms, None)

    def plan_async(self, session_id: str, time_ms: Optional[float] = None,
                   simulations: Optional[int] = None,
                   cpu_ms: Optional[float] = None) -> PlanFuture:
        """plan() in a thread of its own: a PlanFuture, whose cancel() stops the server's search
        (while the robot still moves, say, and a new observation makes the plan moot)."""
        return PlanFuture(lambda call: self._plan(session_id, time_ms, simulations, cpu_ms, call))

    def _plan(self, session_id: str, time_ms: Optional[float], simulations: Optional[int],
              cpu_ms: Optional[float], call: Optional[_Call]) -> Plan:
        budget: Dict[str, Any] = {}
        if time_ms is not None:
            budget["timeMs"] = time_ms
        if cpu_ms is not None:
            budget["cpuMs"] = cpu_ms
        if simulations is not None:
            budget["simulations"] = simulations
        body = {"budget": budget} if budget else {}
        return _typed(lambda j: Plan.from_json(j, self),
                      self._call("POST", f"/v1/sessions/{session_id}:plan", body, call=call))

    def observe(self, session_id: str, action_id: str,
                robot_state: Optional[RobotConfig] = None,
                detections: Optional[List[Detection]] = None, succeeded: bool = True,
                body: Optional[Dict[str, Any]] = None,
                point_cloud: Optional[PointCloud] = None, image: Optional[bytes] = None,
                camera: Optional[Dict[str, float]] = None,
                semantic_scores: Optional[Dict[str, float]] = None,
                image_boxes: Optional[List[ImageBox]] = None) -> Observation:
        """Reports the outcome of `action_id`: either `detections`, or raw sensor data for the
        server's perception (`point_cloud`, with the PNG/JPEG bytes of `image` and the `camera`
        intrinsics {width, height, fx, fy, cx, cy}; `image_boxes`, the robot's own detector's
        boxes of the target, score the objects in place of the server's matching of the image
        against the target's photos). `body` may carry a ready :observe body (as the simulated
        robot produces); the typed arguments are used otherwise."""
        if body is None:
            body = {"succeeded": succeeded}
            if robot_state is not None:
                body["robotState"] = robot_state.to_json()
            if detections is not None:
                body["detections"] = [d.to_json() for d in detections]
            if point_cloud is not None:
                body["pointCloud"] = point_cloud.to_json()
            if image is not None:
                body["image"] = {"encoding": "jpeg" if image[:3] == b"\xff\xd8\xff" else "png",
                                 "data": base64.b64encode(image).decode()}
            if camera is not None:
                body["camera"] = dict(camera)
            if semantic_scores is not None:
                body["semanticScores"] = dict(semantic_scores)
            if image_boxes is not None:
                body["imageBoxes"] = [b.to_json() for b in image_boxes]
        body = dict(body, actionId=action_id)
        j = self._call("POST", f"/v1/sessions/{session_id}:observe", body)
        return _typed(lambda j: Observation(done=j["done"], reward=j["reward"],
                                            session=Session.from_json(j["session"], self),
                                            perception=j.get("perception")), j)

    def belief(self, session_id: str) -> Dict[str, Any]:
        return self._call("GET", f"/v1/sessions/{session_id}/belief")

    def belief_png(self, session_id: str) -> bytes:
        return self._call("GET", f"/v1/sessions/{session_id}/belief", params={"format": "png"},
                          raw=True)
