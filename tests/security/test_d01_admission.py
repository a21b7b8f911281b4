"""D1's admission counts each request once. A waiter handed a slot is still ``waiting`` until it
resumes; shedding on ``waiting`` alone turned a full-but-not-overfull queue into a 503 (the
flaky CI run of stop 27)."""

from __future__ import annotations

import asyncio

from service.api.guard import Admission


def test_a_request_arriving_as_a_slot_is_handed_on_is_queued_not_shed():
    async def scenario():
        adm = Admission(active=2, queued=3, timeout_s=30)
        assert await adm.enter() and await adm.enter()
        waiters = [asyncio.create_task(adm.enter()) for _ in range(3)]
        await asyncio.sleep(0)
        assert (adm.inside, adm.waiting) == (2, 3)
        assert not await adm.enter()  # 2 + 3 in the system: the sixth is shed
        adm.leave()  # hands the slot to the first waiter, which has not resumed yet
        late = asyncio.create_task(adm.enter())  # 4 in the system: it must queue
        await asyncio.sleep(0.01)
        assert not late.done() and (adm.inside, adm.waiting) == (2, 3)
        assert adm.shed == 1
        for _ in range(4):
            adm.leave()
            await asyncio.sleep(0.01)
        assert all(t.result() for t in waiters) and late.result()
        return adm

    adm = asyncio.run(scenario())
    assert adm.shed == 1


def test_a_waiter_that_times_out_gives_no_permit_away():
    async def scenario():
        adm = Admission(active=1, queued=2, timeout_s=0.05)
        assert await adm.enter()
        assert not await adm.enter()  # waited 50 ms, then shed
        adm.leave()
        assert await adm.enter()  # the permit came back whole
        assert (adm.inside, adm.waiting, adm.shed) == (1, 0, 1)

    asyncio.run(scenario())
