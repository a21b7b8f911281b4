"""alarm lifecycle and temperature: operation temperature, SCADA temperature, shelving,
out of service, first-out, and the audit trail of alarm actions

Revision ID: 0007
Revises: 0005
"""
from alembic import op
import sqlalchemy as sa


revision = '0007'
down_revision = '0006'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('operations') as b:
        b.add_column(sa.Column('temperature_c', sa.Float(), nullable=True))
        b.add_column(sa.Column('temperature_source', sa.String(16), nullable=True))
    with op.batch_alter_table('breakers') as b:
        b.add_column(sa.Column('scada_temperature_c', sa.Float(), nullable=True))
        b.add_column(sa.Column('scada_temperature_at', sa.DateTime(timezone=True), nullable=True))
        b.add_column(sa.Column('out_of_service_since', sa.DateTime(timezone=True), nullable=True))
        b.add_column(sa.Column('out_of_service_by', sa.String(120), nullable=True))
        b.add_column(sa.Column('out_of_service_reason', sa.Text(), nullable=True))
    with op.batch_alter_table('alarms') as b:
        b.add_column(sa.Column('first_out', sa.Boolean(), nullable=False, server_default=sa.true()))
        b.add_column(sa.Column('shelved_until', sa.DateTime(timezone=True), nullable=True))
        b.add_column(sa.Column('shelved_at', sa.DateTime(timezone=True), nullable=True))
        b.add_column(sa.Column('shelved_by', sa.String(120), nullable=True))
        b.add_column(sa.Column('shelve_reason', sa.Text(), nullable=True))
    op.create_table(
        'alarm_actions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('breaker_id', sa.Integer(), nullable=False),
        sa.Column('alarm_id', sa.Integer(), nullable=True),
        sa.Column('action', sa.String(24), nullable=False),
        sa.Column('by', sa.String(120), nullable=False),
        sa.Column('at', sa.DateTime(timezone=True), nullable=False),
        sa.Column('reason', sa.Text(), nullable=False, server_default=''),
        sa.Column('until', sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['alarm_id'], ['alarms.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_index('ix_alarm_actions_breaker', 'alarm_actions', ['breaker_id', 'at'])


def downgrade() -> None:
    op.drop_index('ix_alarm_actions_breaker', table_name='alarm_actions')
    op.drop_table('alarm_actions')
    with op.batch_alter_table('alarms') as b:
        for c in ('shelve_reason', 'shelved_by', 'shelved_at', 'shelved_until', 'first_out'):
            b.drop_column(c)
    with op.batch_alter_table('breakers') as b:
        for c in ('out_of_service_reason', 'out_of_service_by', 'out_of_service_since',
                  'scada_temperature_at', 'scada_temperature_c'):
            b.drop_column(c)
    with op.batch_alter_table('operations') as b:
        b.drop_column('temperature_source')
        b.drop_column('temperature_c')
