"""A consumer's GCN session outlives its token, as far as a loopback broker can show it.

The service's own consumer (:class:`~mushrooms.daemon.kafka.consumer.NoticeConsumer`, on GCN's path:
gcn-kafka with a client id and secret, OpenID Connect client credentials) reads from librdkafka's mock
cluster through :class:`sasl_gate.SaslGate`, which authenticates OAUTHBEARER like GCN's brokers: a
token is refused once expired (``{"status":"invalid_token"}``) or when the token endpoint did not issue
it, a session lasts as long as its token and a connection that outlives it without re-authenticating is
closed.  The token endpoint (:class:`sasl_gate.TokenEndpoint`, on a loopback HTTP server) hands out
tokens of a few seconds.  Over several lifetimes every message
must be consumed and committed, the endpoint asked again and again, and live connections
re-authenticated in place (KIP-368).  A client that does not refresh its token is refused by the gate and
consumes nothing more (``benchmarks/attacks/token_refresh_gate.py stale``: 0 of 13).  With tokens of a few
seconds a loaded machine may present a token in its last tenths of a second too late, which the gate
refuses and the client recovers from by reconnecting; that is counted, not failed, so nothing here
depends on the machine's speed.  The loop runs until the endpoint has been asked several times.
"""

from __future__ import annotations

import threading
import time

from sasl_gate import SaslGate, TokenEndpoint

from mushrooms.daemon.credentials import Credentials
from mushrooms.daemon.kafka.consumer import NoticeConsumer
from mushrooms.daemon.settings import KafkaConfig
from mushrooms.tool.loopback_broker import LoopbackBroker

LIFETIME_S = 3  # the token's lifetime (s): librdkafka refreshes at 80 %, re-authenticates at 90 %
IDLE_LIFETIMES = 3  # the consumer is not polled for this many token lifetimes (a stalled loop)


def test_a_consumer_session_outlives_token_refreshes_and_an_idle_spell(loopback):
    """Polled, then not polled for three token lifetimes, then polled again: every message arrives.

    gcn-kafka 0.3.3 on confluent-kafka 2.10.1 (Python ``oauth_cb``, served only from ``poll``) got 1 of 29
    messages in this scenario (benchmarks/results/attacks/trusted_round5/alerts/15_token_refresh_idle_old_clients.txt);
    the required versions refresh in librdkafka's own thread and get them all.
    """
    tokens = TokenEndpoint(loopback, "mushrooms-test", "s3cret", lifetime_s=LIFETIME_S)
    with LoopbackBroker() as broker:
        topic = f"igwn.gwalert.{time.time_ns()}"
        broker.ensure_topic(topic)
        gate = SaslGate(broker.bootstrap, tokens)
        cfg = KafkaConfig(topics=(topic,), group_id="mushrooms-token", assignment="manual", poll_timeout_s=0.2)
        consumer = NoticeConsumer(cfg, credentials=Credentials("mushrooms-test", "s3cret", "test"), overrides={
            "bootstrap.servers": gate.bootstrap, "security.protocol": "sasl_plaintext",
            "sasl.oauthbearer.token.endpoint.url": tokens.url})
        sent, got, polling, done = [], [], threading.Event(), threading.Event()
        polling.set()

        def consume() -> None:
            while not done.is_set() or len(got) < len(sent):
                polling.wait()
                r = consumer.poll()
                if r is not None:
                    got.append(r.value)
                    consumer.commit(r)  # synchronous, as the service commits: a dead session hangs or fails here

        def produce_until(n: int, at_least_s: float = 0.0) -> None:
            start, end = time.monotonic(), time.monotonic() + 120  # a hang guard only
            while (tokens.asked < n or time.monotonic() - start < at_least_s) and time.monotonic() < end:
                sent.append(f"notice {len(sent)}".encode())
                broker.produce(topic, sent[-1])
                time.sleep(0.5)

        reader = threading.Thread(target=consume, daemon=True)
        reader.start()
        try:
            produce_until(2)  # polled: the first token and its first refresh
            polling.clear()
            produce_until(0, IDLE_LIFETIMES * LIFETIME_S)  # not polled for three lifetimes
            polling.set()
            produce_until(tokens.asked + 2)  # polled again: two more refreshes (a client that lost its token:
            # the endpoint is not asked again and the hang guard ends this)
            done.set()
            reader.join(timeout=60)
        finally:
            done.set()
            polling.set()
            if not reader.is_alive():  # closing a consumer another thread is blocked in would crash the process
                consumer.close()
            gate.close()
    assert not reader.is_alive(), f"the consumer stopped after {len(got)} of {len(sent)} messages; {vars(gate)}"
    assert sorted(got) == sorted(sent), f"{len(got)} of {len(sent)} messages; {vars(gate)}"
    assert tokens.asked >= 4 and tokens.refused == 0, vars(tokens)
    assert gate.reauthentications >= 1 and gate.subjects == {"mushrooms-test"}, vars(gate)
