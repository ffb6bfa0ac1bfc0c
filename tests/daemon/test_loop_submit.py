"""A re-plan goes to ZTF's queue when ``[submit]`` is on: the existing Submitter replaces the event's queue.

The notice is planned from now (wall clock: a queue's validity window must not
have ended), the plan's first 10 exposures are executed, the telescope closes
for 2 h, and the re-plan (the event's revision 2) is submitted to the Kowalski
contract server on loopback under the re-plan's own names, the first queue deleted only after.
"""

from __future__ import annotations

import dataclasses

from astropy.time import Time, TimeDelta

from mushrooms.daemon.loop_settings import LoopConfig
from mushrooms.daemon.intake.pipeline import NoticePipeline
from mushrooms.daemon.submission.submitter import queue_name_base, submissions
from mushrooms.handlers.executed import write_jsonl
from mushrooms.scheduler_core.executed import ExecutedExposure

from contract_servers import KowalskiContract, loopback_server
from test_submissions import TOKEN, World, _config

SID = "MS181101ab"


def test_a_closure_re_plan_replaces_the_events_queue(tmp_path):
    server = loopback_server()
    try:
        kowalski = KowalskiContract(server, TOKEN)
        executed = tmp_path / "executed.jsonl"
        config = dataclasses.replace(_config(kowalski.url), loop=LoopConfig(executed_source=f"file:{executed}"))
        world = World(tmp_path / "state.sqlite", config)
        try:
            assert isinstance(world.pipeline, NoticePipeline) and world.pipeline.loop.enabled
            world.notice("MS181101ab-preliminary.json")
            assert world.submitter.step() == 0
            first = world.store.plans(SID)[-1]["document"]
            obs = first["observations"]
            write_jsonl([ExecutedExposure(o["field_id"], o["filter"], Time(o["start"].rstrip("Z"), scale="utc"),
                                          o["exposure_s"], 1.0, "processed") for o in obs[:10]], executed)
            reopening = Time(obs[9]["end"].rstrip("Z"), scale="utc") + TimeDelta(7200.0, format="sec")
            acc = world.pipeline.replan_closure(SID, reopening.isot + "Z", "test:closure")
            assert acc.action == "replan", acc
            out = world.pipeline.run_job(acc.job)
            assert out.decision == "replan" and out.revision == 2, out
            assert world.submitter.step() == 0
            r1, r2 = queue_name_base("GW", first["plan_id"], SID), queue_name_base("GW", out.plan_id, SID)
            held = list(kowalski.queues)
            assert held and all(n.startswith(r2 + "_") for n in held)  # the re-plan's whole set, nothing of r1
            requests = [line.split()[:3] for line in kowalski.lines()]
            puts2 = [i for i, (m, _, n) in enumerate(requests) if m == "PUT" and n.startswith(r2 + "_")]
            deletes1 = [i for i, (m, _, n) in enumerate(requests) if m == "DELETE" and n.startswith(r1 + "_")]
            assert puts2 and deletes1 and max(puts2) < min(deletes1)  # every new queue before any old one goes
            assert [(s.plan_id, s.state) for s in submissions(world.store) if s.state != "skipped"] == [
                (first["plan_id"], "replaced"), (out.plan_id, "submitted")]
            fields = {t["field_id"] for n in held for t in kowalski.queues[n]["targets"]}
            new = world.store.plans(SID)[-1]["document"]
            assert fields == {o["field_id"] for o in new["observations"]}
        finally:
            world.store.close()
    finally:
        server.clear()
        server.stop()
