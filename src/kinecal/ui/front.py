"""The workbench's own HTTP server on 127.0.0.1: the page, its script, the files the page
wrote, and the files dropped on it.

viser serves its client (one HTML file bundled in its wheel, no CDN) and a websocket on a
port of its own. This server, on the port the user asked for, serves that same client
with two additions put into its ``<head>``: the address of viser's websocket (the client
reads it from the ``websocket`` search parameter) and kinecal's script
(``static/workbench.js``: files dropped anywhere on the page, reports opened over the 3D
view). Under ``/kinecal/files/`` it serves only the files the workbench registered (a
report, a plan); ``POST /kinecal/drop`` hands a dropped file to the workbench, which
answers with what it made of it, or the command line's error text.
"""

from __future__ import annotations

import gzip
import json
import mimetypes
import threading
from collections.abc import Callable
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from pathlib import Path
from urllib.parse import parse_qs, unquote, urlsplit

from kinecal.errors import InputError

__all__ = ["FrontServer", "client_page"]

#: the largest file accepted by a drop (bytes): a measurement file of a million rows
MAX_DROP = 256 * 1024 * 1024
_STATIC = ("workbench.js", "workbench.css")


def client_page(viser_port: int) -> bytes:
    """viser's client page with the websocket address and kinecal's script in its head."""
    import viser

    html = (Path(viser.__file__).parent / "client" / "build" / "index.html").read_text(
        encoding="utf-8")
    head = (
        "<script>(function(){var u=new URL(window.location.href);"
        "if(!u.searchParams.has('websocket')){u.searchParams.set('websocket',"
        f"'ws://127.0.0.1:{viser_port}');"
        "window.history.replaceState(null,'',u.pathname+'?'+u.searchParams.toString());}"
        "})();</script>"
        '<link rel="stylesheet" href="/kinecal/static/workbench.css">'
        '<script defer src="/kinecal/static/workbench.js"></script>'
        "<title>kinecal workbench</title>")
    at = html.index("<head>") + len("<head>")
    return (html[:at] + head + html[at:]).encode("utf-8")


class FrontServer:
    """The page's server (module docstring), serving in a thread of its own.

    Parameters
    ----------
    port : int
        Port on 127.0.0.1 (0: any free port).
    viser_port : int
        Port of viser's websocket on 127.0.0.1.
    on_drop : callable
        ``on_drop(name, content) -> (ok, message)`` for a file dropped on the page.
    """

    def __init__(self, port: int, viser_port: int,
                 on_drop: Callable[[str, bytes], tuple[bool, str]]) -> None:
        self._page = gzip.compress(client_page(viser_port), compresslevel=6)
        self._files: dict[str, Path] = {}
        self._lock = threading.Lock()
        self.on_drop = on_drop
        handler = _handler(self)
        try:
            self.httpd = ThreadingHTTPServer(("127.0.0.1", port), handler)
        except OSError as exc:
            raise InputError(f"cannot serve on 127.0.0.1:{port}: {exc.strerror}; choose "
                             "another port", option="--port") from None
        self.httpd.daemon_threads = True
        self.port = int(self.httpd.server_address[1])
        self._thread = threading.Thread(target=self.httpd.serve_forever, name="kinecal-ui-http",
                                        daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        """The page's address."""
        return f"http://127.0.0.1:{self.port}/"

    def publish(self, key: str, path: Path) -> str:
        """Serve the file `path` at ``/kinecal/files/KEY``; returns that address."""
        with self._lock:
            self._files[key] = Path(path)
        return f"/kinecal/files/{key}"

    def lookup(self, key: str) -> Path | None:
        with self._lock:
            return self._files.get(key)

    def close(self) -> None:
        """Stop serving."""
        self.httpd.shutdown()
        self.httpd.server_close()


def _handler(front: FrontServer) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        server_version = "kinecal-ui"

        def log_message(self, format, *args):
            return  # quiet: the terminal shows the address only

        def _host_ok(self) -> bool:
            # a page of another site reaching 127.0.0.1 through a name of its own (DNS
            # rebinding) sends its own host name: refused
            host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
            return host in ("127.0.0.1", "localhost")

        def _send(self, status: int, body: bytes, kind: str, gz: bool = False) -> None:
            self.send_response(status)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            if gz:
                self.send_header("Content-Encoding", "gzip")
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self):
            if not self._host_ok():
                return self._send(HTTPStatus.FORBIDDEN, b"forbidden", "text/plain")
            path = unquote(urlsplit(self.path).path)
            if path in ("/", "/index.html"):
                if "gzip" in self.headers.get("Accept-Encoding", ""):
                    return self._send(HTTPStatus.OK, front._page, "text/html; charset=utf-8",
                                      gz=True)
                return self._send(HTTPStatus.OK, gzip.decompress(front._page),
                                  "text/html; charset=utf-8")
            if path.startswith("/kinecal/static/") and path.rsplit("/", 1)[1] in _STATIC:
                name = path.rsplit("/", 1)[1]
                body = resources.files("kinecal.ui").joinpath("static", name).read_bytes()
                kind = "text/css" if name.endswith(".css") else "application/javascript"
                return self._send(HTTPStatus.OK, body, kind + "; charset=utf-8")
            if path.startswith("/kinecal/files/"):
                file = front.lookup(path[len("/kinecal/files/"):])
                if file is not None and file.is_file():
                    kind = mimetypes.guess_type(file.name)[0] or "application/octet-stream"
                    if kind.startswith("text/"):
                        kind += "; charset=utf-8"
                    return self._send(HTTPStatus.OK, file.read_bytes(), kind)
            return self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")

        def do_POST(self):
            if not self._host_ok():
                return self._send(HTTPStatus.FORBIDDEN, b"forbidden", "text/plain")
            url = urlsplit(self.path)
            if url.path != "/kinecal/drop":
                return self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")
            name = Path(parse_qs(url.query).get("name", ["dropped"])[0]).name or "dropped"
            size = int(self.headers.get("Content-Length") or 0)
            if size > MAX_DROP:
                ok, message = False, (f"kinecal: error: {name}: {size} bytes, more than the "
                                      f"{MAX_DROP // 2**20} MiB a dropped file may have")
            else:
                ok, message = front.on_drop(name, self.rfile.read(size))
            body = json.dumps({"ok": ok, "message": message}).encode("utf-8")
            return self._send(HTTPStatus.OK, body, "application/json")

    return Handler
