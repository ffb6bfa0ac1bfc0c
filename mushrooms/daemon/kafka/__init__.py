"""The Kafka side: the GCN notice consumer, the outbound plan topic, librdkafka's log and broker health.

``consumer``    gcn-kafka consumer, manual offset commits, offset-jump checks
``sink``        the outbound Kafka topic (idempotent producer, acks=all)
``broker_log``  librdkafka's log lines and the broker-health view shared by both

Imports nothing, so a caller loads only the module it needs.
"""
