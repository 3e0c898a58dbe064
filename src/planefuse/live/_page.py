"""The live page: a local web server (aiohttp) pushing the run's state to one page over a WebSocket.

``GET /`` the page (with the newest state in it, drawn at once), ``GET /ws`` the WebSocket (one JSON message per published state, the newest only: a slow
browser skips states, it never slows the run), ``GET /state.json`` the newest state (for programs). The server
runs its own event loop in a daemon thread; :meth:`LivePage.publish` is called from the run's thread. It binds to
127.0.0.1 unless told otherwise (:class:`planefuse.live.LiveSettings` ``host``).
"""

from __future__ import annotations

import asyncio
import json
import threading

__all__ = ["LivePage", "PAGE_HTML"]


class LivePage:
    """The server, started with :meth:`start` and stopped with :meth:`stop`.

    Parameters
    ----------
    host : str
        Interface to bind (``127.0.0.1``: this machine only).
    port : int
        TCP port (0: any free port; :attr:`port` is the one bound once started).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        self.host, self.port = host, int(port)
        self._state = "{}"
        self._version = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._changed: asyncio.Condition | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._runner = None

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def start(self) -> None:
        """Start serving (returns once the port is bound).

        Raises
        ------
        ImportError
            aiohttp is not installed.
        OSError
            The port cannot be bound (in use, or the interface does not exist).
        """
        try:
            import aiohttp  # noqa: F401
        except ImportError:
            raise ImportError("the live page needs aiohttp: pip install 'planefuse[live]' (or run without the page: "
                              "serve: false, --no-page)") from None
        self._thread = threading.Thread(target=self._serve, name="planefuse-live-page", daemon=True)
        self._thread.start()
        self._ready.wait(10.0)
        if self._error is not None:
            raise OSError(f"live page on {self.host}:{self.port}: {self._error}") from self._error

    def publish(self, state: dict) -> None:
        """Make ``state`` (JSON-ready) the newest state (thread-safe)."""
        text = json.dumps(state, separators=(",", ":"))
        loop = self._loop
        if loop is None:
            self._state = text
            return
        loop.call_soon_threadsafe(self._set, text)

    def _set(self, text: str) -> None:
        self._state = text
        self._version += 1
        asyncio.ensure_future(self._notify())

    async def _notify(self) -> None:
        async with self._changed:
            self._changed.notify_all()

    def stop(self) -> None:
        """Close every connection and stop the server."""
        loop = self._loop
        if loop is not None and self._runner is not None:
            fut = asyncio.run_coroutine_threadsafe(self._runner.cleanup(), loop)
            try:
                fut.result(5.0)
            except Exception:  # noqa: BLE001 - closing anyway
                pass
            loop.call_soon_threadsafe(loop.stop)
        if self._thread is not None:
            self._thread.join(5.0)

    def _serve(self) -> None:
        from aiohttp import WSMsgType, web

        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        self._changed = asyncio.Condition()

        async def index(request):
            # the newest state comes with the page (drawn at once), the WebSocket brings the next ones
            initial = self._state.replace("</", "<\\/")
            return web.Response(text=PAGE_HTML.replace("/*INITIAL_STATE*/null", initial), content_type="text/html")

        async def state(request):
            return web.Response(text=self._state, content_type="application/json")

        async def ws(request):
            sock = web.WebSocketResponse(heartbeat=10.0)
            await sock.prepare(request)
            seen = -1

            async def sender():
                nonlocal seen
                while not sock.closed:
                    if seen != self._version:
                        seen = self._version
                        await sock.send_str(self._state)
                    async with self._changed:
                        try:
                            await asyncio.wait_for(self._changed.wait(), 1.0)
                        except asyncio.TimeoutError:
                            pass

            task = asyncio.ensure_future(sender())
            try:
                async for msg in sock:  # the page sends nothing; this ends when it closes
                    if msg.type == WSMsgType.ERROR:
                        break
            finally:
                task.cancel()
            return sock

        app = web.Application()
        app.add_routes([web.get("/", index), web.get("/ws", ws), web.get("/state.json", state)])
        runner = web.AppRunner(app, access_log=None)
        try:
            loop.run_until_complete(runner.setup())
            site = web.TCPSite(runner, self.host, self.port)
            loop.run_until_complete(site.start())
            self.port = int(runner.addresses[0][1])
        except BaseException as exc:  # noqa: BLE001 - reported by start()
            self._error = exc
            self._ready.set()
            return
        self._runner = runner
        self._loop = loop
        self._ready.set()
        try:
            loop.run_forever()
        finally:
            loop.close()


PAGE_HTML = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>planefuse live</title>
<style>
body{font-family:system-ui,sans-serif;margin:12px;background:#f6f6f4;color:#222}
h1{font-size:18px;margin:0 0 8px}
#top{display:flex;gap:16px;align-items:flex-start;flex-wrap:wrap}
#plan{background:#fff;border:1px solid #ccc}
#cams{display:flex;flex-wrap:wrap;gap:8px;max-width:620px}
#cams figure{margin:0;background:#fff;border:1px solid #ccc;padding:4px}
#cams img{display:block;width:290px}
#cams figcaption{font-size:12px}
table{border-collapse:collapse;font-size:13px;margin-top:8px}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td:first-child,th:first-child{text-align:left}
.live{color:#080}.retrying,.connecting{color:#b60}.error,.ended,.stopped{color:#b00}
#status{font-size:13px;margin:4px 0}
</style></head><body>
<h1>planefuse live</h1>
<div id="status">connecting&hellip;</div>
<div>tracks: <b><span id="track-count">0</span></b> &middot; time <span id="time">-</span> s &middot;
latency p50 <span id="lat50">-</span> ms, p95 <span id="lat95">-</span> ms &middot; <span id="warm">-</span></div>
<div id="top">
<div><canvas id="plan" width="480" height="480"></canvas><ul id="tracks"></ul></div>
<div><div id="cams"></div>
<table id="health"><thead><tr><th>camera</th><th>state</th><th>rate Hz</th><th>used</th><th>skipped</th>
<th>dropped</th><th>late</th><th>reconnects</th><th>lag ms</th><th>last error</th></tr></thead><tbody></tbody></table>
</div></div>
<script>
const colours=["#e6194b","#3cb44b","#4363d8","#f58231","#911eb4","#42d4f4","#f032e6","#9a6324","#469990","#800000"];
const col=id=>colours[id%colours.length];
const occ=new Image();let last=null;
function draw(s){
  const c=document.getElementById("plan"),g=c.getContext("2d");
  const [x0,x1,y0,y1]=s.extent_m;const sc=Math.min(480/(x1-x0),480/(y1-y0));
  c.width=Math.round((x1-x0)*sc);c.height=Math.round((y1-y0)*sc);
  const X=x=>(x-x0)*sc,Y=y=>(y1-y)*sc;
  g.fillStyle="#fff";g.fillRect(0,0,c.width,c.height);
  if(occ.complete&&occ.naturalWidth){g.imageSmoothingEnabled=false;g.globalAlpha=0.85;g.drawImage(occ,0,0,c.width,c.height);g.globalAlpha=1}
  g.strokeStyle="#e0a000";g.lineWidth=2;
  for(const d of s.detections||[]){const u=X(d[0]),v=Y(d[1]);g.beginPath();g.moveTo(u-10,v);g.lineTo(u+10,v);
    g.moveTo(u,v-10);g.lineTo(u,v+10);g.stroke()}
  for(const t of s.tracks){g.strokeStyle=col(t.id);g.lineWidth=2;g.beginPath();
    t.trail.forEach((p,i)=>{i?g.lineTo(X(p[0]),Y(p[1])):g.moveTo(X(p[0]),Y(p[1]))});g.stroke();
    g.fillStyle=col(t.id);g.beginPath();g.arc(X(t.x_m),Y(t.y_m),6,0,7);g.fill();
    g.fillStyle="#000";g.font="13px sans-serif";g.fillText(String(t.id),X(t.x_m)+8,Y(t.y_m)-8)}
}
function show(s){
  last=s;
  document.getElementById("track-count").textContent=s.tracks.length;
  document.getElementById("time").textContent=s.time_s.toFixed(2);
  document.getElementById("lat50").textContent=s.latency_ms_p50==null?"-":s.latency_ms_p50.toFixed(0);
  document.getElementById("lat95").textContent=s.latency_ms_p95==null?"-":s.latency_ms_p95.toFixed(0);
  document.getElementById("warm").textContent=s.warm_up;
  document.getElementById("status").textContent=s.status;
  const ul=document.getElementById("tracks");ul.innerHTML="";
  for(const t of s.tracks){const li=document.createElement("li");li.className="track";li.dataset.id=t.id;
    li.textContent=`#${t.id}: (${t.x_m.toFixed(2)}, ${t.y_m.toFixed(2)}) m`;li.style.color=col(t.id);ul.appendChild(li)}
  if(s.occupancy_png){occ.onload=()=>draw(last);occ.src="data:image/png;base64,"+s.occupancy_png}
  draw(s);
  const cams=document.getElementById("cams");
  for(const [name,jpg] of Object.entries(s.cameras)){
    let f=document.getElementById("cam-"+name);
    if(!f){f=document.createElement("figure");f.id="cam-"+name;f.innerHTML=`<img><figcaption>${name}</figcaption>`;cams.appendChild(f)}
    if(jpg)f.querySelector("img").src="data:image/jpeg;base64,"+jpg}
  const tb=document.querySelector("#health tbody");tb.innerHTML="";
  for(const h of s.health){const tr=document.createElement("tr");
    tr.innerHTML=`<td>${h.name}</td><td class="${h.state}">${h.state}</td><td>${h.rate_hz}</td><td>${h.used}</td>`+
      `<td>${h.skipped}</td><td>${h.dropped}</td><td>${h.late}</td><td>${h.reconnects}</td>`+
      `<td>${h.lag_s==null?"-":(1000*h.lag_s).toFixed(0)}</td><td>${h.last_error}</td>`;tb.appendChild(tr)}
}
function connect(){
  const ws=new WebSocket((location.protocol==="https:"?"wss://":"ws://")+location.host+"/ws");
  ws.onmessage=e=>{const s=JSON.parse(e.data);if(s.tracks)show(s)};
  ws.onclose=()=>{document.getElementById("status").textContent="disconnected; retrying";setTimeout(connect,1000)};
}
const initial=/*INITIAL_STATE*/null;
if(initial&&initial.tracks)show(initial);
connect();
</script></body></html>
"""
