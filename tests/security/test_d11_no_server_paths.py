"""D11: answers never tell a reader or an operator where the service keeps its files."""

from __future__ import annotations

from pathlib import Path

from service.errors import redact_paths
from service.storage import crud
from service.storage.models import utcnow
from service.storage.spool import Spool

from .test_d15_session_rotation import sign_in


def test_redaction_keeps_file_names_only():
    assert redact_paths("capture file missing: /srv/hvcb/var/captures/2026/1125/k.cfg") == "capture file missing: k.cfg"
    assert redact_paths("C:\\hvcb\\var\\x.dat is gone") == "x.dat is gone"
    assert redact_paths("see https://example.org/a/b") == "see https://example.org/a/b"


def test_fit_failure_pruned_curve_and_pages_carry_no_server_path(env):
    data_dir = str(Path(env.settings.data_dir).resolve())
    missing = f"{data_dir}/captures/2026/0101/gone.cfg"
    with env.Session() as s, s.begin():
        op, _ = crud.create_operation(s, capture_key=Spool.new_key(), breaker_id=1, kind="open", occurred_at=utcnow(),
                                      source="upload", capture_path=missing, capture_sha256="0" * 64, flags=[],
                                      sample_rate=128000.0, n_samples=10)
        crud.store_fit_failure(s, operation_id=op.id, reason=f"capture file missing: {missing}")
        op_id = op.id
    answers = [env.client.get(f"/api/v1/operations/{op_id}", headers=env.h("reader")),
               env.client.get(f"/api/v1/breakers/1/operations", headers=env.h("operator")),
               env.client.get(f"/api/v1/operations/{op_id}/curve", headers=env.h("reader"))]
    assert answers[0].status_code == 200 and "gone.cfg" in answers[0].text
    assert answers[2].status_code == 410
    sign_in(env.client, env.keys["reader"])
    answers += [env.client.get(f"/operations/{op_id}"), env.client.get(f"/ui/operations/{op_id}/curves.json")]
    for r in answers:
        assert data_dir not in r.text and "/captures/" not in r.text, r.url
