"""fit_versions, refit_runs: refits keep the superseded results; the fits row is the newest

Revision ID: 0004
Revises: 0003_web
"""
from alembic import op
import sqlalchemy as sa


revision = '0004'
down_revision = '0003_web'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'refit_runs',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('breaker_id', sa.Integer(), nullable=True),
        sa.Column('since', sa.DateTime(timezone=True), nullable=True),
        sa.Column('status', sa.String(length=12), nullable=False),
        sa.Column('reason', sa.Text(), nullable=True),
        sa.Column('requested_by', sa.String(length=120), nullable=True),
        sa.Column('total', sa.Integer(), nullable=False),
        sa.Column('done', sa.Integer(), nullable=False),
        sa.Column('failed', sa.Integer(), nullable=False),
        sa.Column('created_at', sa.DateTime(timezone=True), nullable=False),
        sa.Column('started_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('finished_at', sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_table(
        'fit_versions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('fit_id', sa.Integer(), nullable=False),
        sa.Column('operation_id', sa.Integer(), nullable=False),
        sa.Column('version', sa.Integer(), nullable=False),
        sa.Column('status', sa.String(length=10), nullable=False),
        sa.Column('failure_reason', sa.Text(), nullable=True),
        sa.Column('parameters', sa.JSON(), nullable=True),
        sa.Column('ci95', sa.JSON(), nullable=True),
        sa.Column('rmse_rad', sa.Float(), nullable=True),
        sa.Column('result', sa.JSON(), nullable=True),
        sa.Column('finished_at', sa.DateTime(timezone=True), nullable=True),
        sa.Column('superseded_at', sa.DateTime(timezone=True), nullable=False),
        sa.Column('superseded_by_run', sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(['fit_id'], ['fits.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['operation_id'], ['operations.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['superseded_by_run'], ['refit_runs.id'], ondelete='SET NULL'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('operation_id', 'version', name='uq_fit_versions_operation_version'),
    )
    with op.batch_alter_table('fits') as batch:
        batch.add_column(sa.Column('version', sa.Integer(), nullable=False, server_default='1'))
        batch.add_column(sa.Column('refit_run_id', sa.Integer(), nullable=True))
        batch.create_foreign_key('fk_fits_refit_run', 'refit_runs', ['refit_run_id'], ['id'],
                                 ondelete='SET NULL')


def downgrade() -> None:
    with op.batch_alter_table('fits') as batch:
        batch.drop_constraint('fk_fits_refit_run', type_='foreignkey')
        batch.drop_column('refit_run_id')
        batch.drop_column('version')
    op.drop_table('fit_versions')
    op.drop_table('refit_runs')
