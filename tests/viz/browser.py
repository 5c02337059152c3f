"""Headless Chromium driven over the DevTools protocol, with every host but loopback unreachable.

The browser resolves no name but 127.0.0.1 (``--host-resolver-rules``) and sends anything not
on loopback to a proxy on a closed loopback port, so an address literal goes nowhere either;
loopback itself bypasses the proxy (Chromium's implicit rule). Chromium's own background
requests are switched off or pointed at that closed port; what is left of them (a net log of
an idle browser shows ``accounts.google.com/ListAccounts``) ends at the closed proxy. :func:`open_page` loads a
page, waits, and returns what it asked for: every request's URL, the console's messages and
exceptions, and a PNG screenshot.
"""
from __future__ import annotations

import asyncio
import base64
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

import websockets

CLOSED_PORT = 9  # discard: nothing listens there on a test machine
FLAGS = (
    "--headless=new", "--no-sandbox", "--no-first-run", "--no-default-browser-check",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--disable-default-apps", "--disable-extensions", "--no-pings", "--disable-domain-reliability",
    "--disable-features=OptimizationHints,MediaRouter,Translate,NetworkTimeServiceQuerying,AccountConsistency",
    "--allow-browser-signin=false", f"--component-updater=url-source=http://127.0.0.1:{CLOSED_PORT}",
    "--metrics-recording-only", "--safebrowsing-disable-auto-update", "--disable-client-side-phishing-detection",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
    f"--proxy-server=http://127.0.0.1:{CLOSED_PORT}",
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
    "--window-size=1280,800", "--remote-debugging-port=0",
)


def chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@dataclass
class PageResult:
    requests: list[str] = field(default_factory=list)  # every URL the page asked the network for
    console: list[tuple[str, str]] = field(default_factory=list)  # (level, text), console API and browser log
    screenshot: bytes = b""  # PNG


def _devtools_port(profile: Path, proc: subprocess.Popen, timeout: float = 30.0) -> int:
    marker = profile / "DevToolsActivePort"
    deadline = time.monotonic() + timeout
    while not marker.exists() or not marker.read_text().strip():
        if proc.poll() is not None or time.monotonic() > deadline:
            raise RuntimeError(f"chromium did not start (exit {proc.poll()})")
        time.sleep(0.1)
    return int(marker.read_text().split()[0])


async def _drive(ws_url: str, url: str, settle: float, ready_js: str | None, timeout: float) -> PageResult:
    result = PageResult()
    async with websockets.connect(ws_url, max_size=2**28) as ws:
        counter = 0
        pending: dict[int, asyncio.Future] = {}

        async def reader() -> None:
            async for raw in ws:
                msg = json.loads(raw)
                if "id" in msg and msg["id"] in pending:
                    pending.pop(msg["id"]).set_result(msg)
                method, params = msg.get("method"), msg.get("params", {})
                if method == "Network.requestWillBeSent":
                    result.requests.append(params["request"]["url"])
                elif method == "Runtime.consoleAPICalled":
                    text = " ".join(str(a.get("value", a.get("description", ""))) for a in params["args"])
                    result.console.append((params["type"], text))
                elif method == "Runtime.exceptionThrown":
                    details = params["exceptionDetails"]
                    result.console.append(("error", details.get("exception", {}).get("description", details["text"])))
                elif method == "Log.entryAdded":
                    entry = params["entry"]
                    result.console.append((entry["level"], f"{entry['source']}: {entry['text']} {entry.get('url', '')}"))

        async def call(method: str, **params) -> dict:
            nonlocal counter
            counter += 1
            future = asyncio.get_running_loop().create_future()
            pending[counter] = future
            await ws.send(json.dumps({"id": counter, "method": method, "params": params}))
            reply = await asyncio.wait_for(future, timeout)
            if "error" in reply:
                raise RuntimeError(f"{method}: {reply['error']}")
            return reply.get("result", {})

        task = asyncio.create_task(reader())
        for domain in ("Network", "Runtime", "Log", "Page"):
            await call(f"{domain}.enable")
        await call("Page.navigate", url=url)
        deadline = time.monotonic() + timeout
        if ready_js is not None:
            while not (await call("Runtime.evaluate", expression=ready_js, returnByValue=True))["result"].get("value"):
                if time.monotonic() > deadline:
                    raise TimeoutError(f"the page never got ready ({ready_js})")
                await asyncio.sleep(0.5)
        await asyncio.sleep(settle)
        shot = await call("Page.captureScreenshot", format="png")
        result.screenshot = base64.b64decode(shot["data"])
        task.cancel()
    return result


def open_page(url: str, settle: float = 5.0, ready_js: str | None = None, timeout: float = 90.0) -> PageResult:
    """Load ``url`` in a fresh headless Chromium; once ``ready_js`` evaluates truthy, wait ``settle``
    seconds and take a screenshot."""
    binary = chromium()
    if binary is None:
        raise FileNotFoundError("chromium is not installed (scripts/setup.sh installs it)")
    # Chromium's helpers may still write to the profile for a moment after the browser is gone
    with tempfile.TemporaryDirectory(prefix="actaim2-chromium-", ignore_cleanup_errors=True) as profile:
        proc = subprocess.Popen([binary, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            port = _devtools_port(Path(profile), proc)
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as reply:
                page = next(t for t in json.load(reply) if t["type"] == "page")
            return asyncio.run(_drive(page["webSocketDebuggerUrl"], url, settle, ready_js, timeout))
        finally:
            proc.terminate()
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
