"""notifications: the outbox of alarm events, each route's progress and the deliveries (issue 38)

Revision ID: 0013
Revises: 0014
"""
from alembic import op
import sqlalchemy as sa


revision = '0013'
down_revision = '0014'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'notification_events',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('key', sa.String(64), nullable=False),
        sa.Column('kind', sa.String(24), nullable=False),
        sa.Column('breaker_id', sa.Integer(), nullable=False),
        sa.Column('alarm_id', sa.Integer(), nullable=True),
        sa.Column('parameter', sa.String(16), nullable=True),
        sa.Column('severity', sa.String(10), nullable=False),
        sa.Column('silenced', sa.Text(), nullable=True),
        sa.Column('payload', sa.JSON(), nullable=False),
        sa.Column('created_at', sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['alarm_id'], ['alarms.id'], ondelete='SET NULL'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('key', name='uq_notification_events_key'),
    )
    op.create_index('ix_notification_events_alarm', 'notification_events', ['alarm_id', 'id'])
    op.create_table(
        'notification_routes',
        sa.Column('name', sa.String(60), nullable=False),
        sa.Column('cursor', sa.Integer(), nullable=False),
        sa.Column('failures', sa.Integer(), nullable=False),
        sa.Column('next_attempt_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('last_error', sa.Text(), nullable=True),
        sa.Column('last_sent_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('lease_owner', sa.String(120), nullable=True),
        sa.Column('lease_until', sa.DateTime(timezone=True), nullable=True),
        sa.Column('created_at', sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint('name'),
    )
    op.create_table(
        'notification_deliveries',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('event_id', sa.Integer(), nullable=False),
        sa.Column('route', sa.String(60), nullable=False),
        sa.Column('message_key', sa.String(64), nullable=True),
        sa.Column('status', sa.String(8), nullable=False),
        sa.Column('attempts', sa.Integer(), nullable=False),
        sa.Column('sent_at', sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['event_id'], ['notification_events.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('event_id', 'route', name='uq_notification_deliveries_event_route'),
    )
    op.create_index('ix_notification_deliveries_pending', 'notification_deliveries', ['route', 'status', 'event_id'])


def downgrade() -> None:
    op.drop_index('ix_notification_deliveries_pending', table_name='notification_deliveries')
    op.drop_table('notification_deliveries')
    op.drop_table('notification_routes')
    op.drop_index('ix_notification_events_alarm', table_name='notification_events')
    op.drop_table('notification_events')
