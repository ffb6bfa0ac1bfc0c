"""Reproduction: a GCN-style OAUTHBEARER session (tests/daemon/sasl_gate.py in front of librdkafka's mock cluster) across
3 s tokens, with the installed gcn-kafka / confluent-kafka: prints produced/consumed and the gate's counters.
Usage: python benchmarks/attacks/token_refresh_gate.py LIFETIME_S [stale|idle] (idle: the reader stops polling for
three token lifetimes, then resumes; stale: the token endpoint hands out
its first token again and again, a client that never refreshes)."""
import sys, time, json, threading, logging
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[2] / "tests" / "daemon"))
from http.server import BaseHTTPRequestHandler, HTTPServer
from sasl_gate import SaslGate, unsecured_jwt
from mushrooms.tool.loopback_broker import LoopbackBroker
import gcn_kafka, confluent_kafka
LIFE = float(sys.argv[1]) if len(sys.argv) > 1 else 3
hits = []
STALE = len(sys.argv) > 2 and sys.argv[2] == "stale"
IDLE = len(sys.argv) > 2 and sys.argv[2] == "idle"  # the reader stops polling for 3 lifetimes, then resumes
FIRST = {}
class H(BaseHTTPRequestHandler):
    def do_POST(self):
        n = int(self.headers.get("Content-Length", 0)); body = self.rfile.read(n)
        hits.append((time.time(), body[:80]))
        tok = FIRST.setdefault("t", unsecured_jwt("mushrooms-test", LIFE)) if STALE else unsecured_jwt("mushrooms-test", LIFE)
        data = json.dumps({"access_token": tok, "token_type": "bearer", "expires_in": LIFE}).encode()
        self.send_response(200); self.send_header("Content-Type", "application/json"); self.send_header("Content-Length", str(len(data))); self.end_headers(); self.wfile.write(data)
    def log_message(self, *a): pass
srv = HTTPServer(("127.0.0.1", 0), H); threading.Thread(target=srv.serve_forever, daemon=True).start()
url = f"http://127.0.0.1:{srv.server_port}/oauth2/token"
b = LoopbackBroker(); b.ensure_topic("igwn.gwalert")
gate = SaslGate(b.bootstrap)
logs = []
c = gcn_kafka.Consumer(config={"bootstrap.servers": gate.bootstrap, "security.protocol": "sasl_plaintext",
     "sasl.oauthbearer.token.endpoint.url": url, "group.id": "g1", "auto.offset.reset": "earliest",
     "enable.auto.commit": False, "logger": logging.getLogger("rdk")},
     client_id="mushrooms-test", client_secret="s3cret", domain="gcn.nasa.gov")
logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
c.subscribe(["igwn.gwalert"])
got = []
state = {"produced": 0}


def reader():
    paused = False
    while True:
        if IDLE and not paused and time.time() - t0 > LIFE:
            paused = True
            time.sleep(3 * LIFE)  # not polled: nothing in Python serves librdkafka's callbacks meanwhile
        for m in c.consume(1, 0.5):
            if m.error():
                print("ERR", m.error(), flush=True)
                continue
            got.append(m.value().decode())
            c.commit(message=m, asynchronous=False)  # synchronous, as the service commits


t0 = time.time()
threading.Thread(target=reader, daemon=True).start()
while time.time() - t0 < 14 + (4 * LIFE if IDLE else 0):
    if state["produced"] < int(time.time() - t0):
        b.produce("igwn.gwalert", f"m{state['produced']}".encode())
        state["produced"] += 1
    time.sleep(0.1)
time.sleep(5)  # the reader's last messages
print("produced", state["produced"], "got", len(got), got[:3], got[-3:])
print("token hits", len(hits), "auth", gate.authentications, "reauth", gate.reauthentications, "refused", gate.refused,
      "expired", gate.expired, flush=True)
__import__("os")._exit(0 if len(got) == state["produced"] and not gate.refused else 1)
