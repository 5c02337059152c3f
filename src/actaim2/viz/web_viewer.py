"""The Rerun web viewer served on loopback with nothing fetched from anywhere else.

The viewer (``re_viewer.js`` + ``re_viewer_bg.wasm``) ships inside the ``rerun-sdk`` wheel's
``rerun`` binary. :func:`viewer_assets` starts that binary's web server once, bound to 127.0.0.1
and with its analytics switched off in a private configuration folder, copies the two files
over loopback and stops it. :class:`ViewerServer` then serves them from memory beside a
recording (``.rrd``) and a page of ours instead of the wheel's ``index.html``, because that page
and the viewer's defaults reach out to the internet:

* the page links a web font from ``fonts.googleapis.com`` (ours uses the browser's own fonts);
* the viewer asks ``api.github.com`` whether a newer release exists
  (``check_for_updates_on_startup``, on by default);
* the viewer posts anonymous usage analytics to ``tel.rerun.io/api/pog`` (PostHog) on start
  and on opening a recording; the wasm build has no switch for it (``rerun analytics disable``
  and the ``notebook`` option do not reach it);
* the welcome screen downloads the example manifest from ``app.rerun.io`` unless given a
  ``manifest_url``.

Our page starts the viewer with the update check off, the welcome screen hidden, the manifest
(empty) and the recording from this server, and nothing persisted in the browser. It answers
every request the page makes to another host itself, before the browser sees it (an empty
JSON response and a console line at debug level): that is how the analytics posts stay on
this machine, and whatever a later viewer version adds would too. The server listens on
127.0.0.1 only.
"""
from __future__ import annotations

import html
import json
import os
import shutil
import socket
import subprocess
import tempfile
import threading
import time
import urllib.request
from functools import partial
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

ASSETS = ("re_viewer.js", "re_viewer_bg.wasm")
CONTENT_TYPES = {".js": "text/javascript", ".wasm": "application/wasm", ".rrd": "application/octet-stream",
                 ".json": "application/json", ".html": "text/html; charset=utf-8"}
LOOPBACK = "127.0.0.1"
RECORDING_PATH = "/recording.rrd"
MANIFEST_PATH = "/examples_manifest.json"
START_TIMEOUT = 30.0  # s for the wheel's web server to answer

PAGE = """<!doctype html>
<html>
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1.0, user-scalable=no">
<link rel="icon" href="data:,">
<title>actaim2 view: __TITLE__</title>
<style>
  html, body { margin: 0; padding: 0; width: 100%; height: 100%; overflow: hidden;
               background: #0d1011; font-family: sans-serif; color: #cad8de; }
  canvas { position: absolute; top: 0; left: 0; width: 100%; height: 100%; }
  #status { position: absolute; top: 45%; width: 100%; text-align: center; }
</style>
</head>
<body>
<div id="status">Loading the viewer...</div>
<canvas id="viewer"></canvas>
<script>
  // Requests to any other host are answered here: nothing leaves this machine.
  (function () {
    const local = (url) => new URL(url, location.href).host === location.host;
    const realFetch = window.fetch.bind(window);
    window.fetch = function (input, init) {
      const url = typeof input === "string" ? input : input.url;
      if (local(url)) return realFetch(input, init);
      console.debug("actaim2 view: not fetched (offline viewer): " + url);
      return Promise.resolve(new Response("{}", {status: 200, headers: {"content-type": "application/json"}}));
    };
    const realOpen = XMLHttpRequest.prototype.open;
    XMLHttpRequest.prototype.open = function (method, url, ...rest) {
      if (!local(url)) {
        console.debug("actaim2 view: not fetched (offline viewer): " + url);
        url = "__MANIFEST__";
      }
      return realOpen.call(this, method, url, ...rest);
    };
  })();
</script>
<script src="re_viewer.js"></script>
<script>
  const status = document.getElementById("status");
  function fail(error) {
    console.error("actaim2 view: the viewer failed: " + error);
    status.textContent = "The viewer failed: " + error;
  }
  wasm_bindgen({module_or_path: "./re_viewer_bg.wasm"}).then(() => {
    const handle = new wasm_bindgen.WebHandle({
      url: [location.origin + "__RECORDING__"],
      manifest_url: location.origin + "__MANIFEST__",
      render_backend: "webgl",
      hide_welcome_screen: true,
      check_for_updates_on_startup: false,
      enable_history: false,
      persist: false,
    });
    window._handle = handle;  // for scripts driving the page (the browser test waits for it)
    return handle.start(document.getElementById("viewer")).then(() => { status.remove(); });
  }).catch(fail);
</script>
</body>
</html>
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind((LOOPBACK, 0))
        return s.getsockname()[1]


def _rerun_binary() -> str:
    import rerun_cli

    binary = Path(rerun_cli.__file__).parent / "rerun"
    if not binary.exists():
        raise FileNotFoundError(f"the rerun-sdk wheel's viewer binary is missing ({binary})")
    return str(binary)


def _offline_environment(home: Path) -> dict[str, str]:
    """The environment of the wheel's binary: its configuration in ``home`` with analytics off."""
    config, data = home / "config", home / "data"
    (config / "rerun").mkdir(parents=True)
    settings = {"analytics_enabled": False, "analytics_id": "offline", "metadata": {},
                "config_file_path": str(config / "rerun" / "analytics.json"),
                "data_dir_path": str(data / "rerun" / "analytics")}
    (config / "rerun" / "analytics.json").write_text(json.dumps(settings))
    return {**os.environ, "XDG_CONFIG_HOME": str(config), "XDG_DATA_HOME": str(data), "XDG_CACHE_HOME": str(home / "cache"),
            "HOME": str(home), "RUST_LOG": "warn"}


def viewer_assets() -> dict[str, bytes]:
    """The web viewer's files as the ``rerun-sdk`` wheel serves them (module docstring)."""
    home = Path(tempfile.mkdtemp(prefix="actaim2-rerun-"))
    web, grpc = free_port(), free_port()
    proc = subprocess.Popen([_rerun_binary(), "--serve-web", "--bind", LOOPBACK, "--web-viewer-port", str(web),
                             "--port", str(grpc)], env=_offline_environment(home),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + START_TIMEOUT
        while True:
            try:
                return {name: urllib.request.urlopen(f"http://{LOOPBACK}:{web}/{name}", timeout=30).read() for name in ASSETS}
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    stderr = proc.communicate(timeout=5)[1].decode(errors="replace") if proc.poll() is not None else ""
                    raise RuntimeError(f"the rerun web viewer server did not start: {stderr[-2000:]}") from None
                time.sleep(0.2)
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(timeout=10)
        shutil.rmtree(home, ignore_errors=True)


class _Handler(BaseHTTPRequestHandler):
    def __init__(self, *args, files: dict[str, tuple[bytes, str]], **kwargs) -> None:
        self.files = files
        super().__init__(*args, **kwargs)

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        path = self.path.split("?", 1)[0]
        if path not in self.files:
            self.send_error(HTTPStatus.NOT_FOUND)
            return
        body, content_type = self.files[path]
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args) -> None:
        """Quiet: a page load is dozens of requests."""


class ViewerServer:
    """Serves the viewer, our page and one recording on ``http://127.0.0.1:<port>/`` from a thread."""

    def __init__(self, recording: Path, title: str, port: int = 0, assets: dict[str, bytes] | None = None) -> None:
        """OSError (the port is taken) before anything else is done."""
        typed: dict[str, tuple[bytes, str]] = {}  # filled below, once the port is ours
        self.httpd = ThreadingHTTPServer((LOOPBACK, port), partial(_Handler, files=typed))
        assets = assets if assets is not None else viewer_assets()
        page = (PAGE.replace("__TITLE__", html.escape(title)).replace("__RECORDING__", RECORDING_PATH)
                .replace("__MANIFEST__", MANIFEST_PATH))
        files = {"/": page.encode(), "/index.html": page.encode(), MANIFEST_PATH: b"[]",
                 RECORDING_PATH: Path(recording).read_bytes(), **{f"/{name}": data for name, data in assets.items()}}
        typed.update({path: (body, CONTENT_TYPES.get(Path(path).suffix or ".html", "application/octet-stream"))
                      for path, body in files.items()})
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    @property
    def url(self) -> str:
        return f"http://{LOOPBACK}:{self.httpd.server_address[1]}/"

    def __enter__(self) -> ViewerServer:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()
