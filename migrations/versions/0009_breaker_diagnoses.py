"""breaker_diagnoses: gap diagnosis of a breaker's last N stored operations (issue 20)

Revision ID: 0009
Revises: 0005
"""
from alembic import op
import sqlalchemy as sa


revision = '0009'
down_revision = '0007'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'breaker_diagnoses',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('breaker_id', sa.Integer(), nullable=False),
        sa.Column('operation', sa.String(length=8), nullable=False),
        sa.Column('last_n', sa.Integer(), nullable=False),
        sa.Column('operation_ids', sa.JSON(), nullable=False),
        sa.Column('skipped', sa.JSON(), nullable=False),
        sa.Column('selection_key', sa.String(length=64), nullable=False),
        sa.Column('dedupe_key', sa.String(length=64), nullable=True),
        sa.Column('status', sa.String(length=10), nullable=False),
        sa.Column('result', sa.JSON(), nullable=True),
        sa.Column('failure_reason', sa.Text(), nullable=True),
        sa.Column('requested_by', sa.String(length=120), nullable=True),
        sa.Column('requested_key_id', sa.Integer(), nullable=True),
        sa.Column('requested_role', sa.String(length=10), nullable=False),
        sa.Column('requested_at', sa.DateTime(timezone=True), nullable=False),
        sa.Column('started_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('finished_at', sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['requested_key_id'], ['api_keys.id'], ondelete='SET NULL'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('dedupe_key', name='uq_breaker_diagnoses_dedupe_key'),
    )
    op.create_index('ix_breaker_diagnoses_breaker', 'breaker_diagnoses', ['breaker_id', 'id'])
    op.create_index('ix_breaker_diagnoses_status', 'breaker_diagnoses', ['status'])


def downgrade() -> None:
    op.drop_index('ix_breaker_diagnoses_status', table_name='breaker_diagnoses')
    op.drop_index('ix_breaker_diagnoses_breaker', table_name='breaker_diagnoses')
    op.drop_table('breaker_diagnoses')
