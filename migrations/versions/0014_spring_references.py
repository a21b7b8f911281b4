"""spring_references: a breaker's commissioning pair, the reference of its spring setting (issue 39)

Revision ID: 0014
Revises: 0011
"""
from alembic import op
import sqlalchemy as sa


revision = '0014'
down_revision = '0011'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'spring_references',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('breaker_id', sa.Integer(), nullable=False),
        sa.Column('opening_id', sa.Integer(), nullable=False),
        sa.Column('closing_id', sa.Integer(), nullable=False),
        sa.Column('known_steps', sa.Float(), nullable=False),
        sa.Column('reading', sa.JSON(), nullable=False),
        sa.Column('recorded_by', sa.String(length=200), nullable=False),
        sa.Column('recorded_at', sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(['breaker_id'], ['breakers.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['opening_id'], ['operations.id'], ondelete='CASCADE'),
        sa.ForeignKeyConstraint(['closing_id'], ['operations.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
    )
    op.create_index('ix_spring_references_breaker_id', 'spring_references', ['breaker_id'])


def downgrade() -> None:
    op.drop_index('ix_spring_references_breaker_id', table_name='spring_references')
    op.drop_table('spring_references')
