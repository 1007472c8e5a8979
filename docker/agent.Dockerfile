# A participant's agent: only the light client (numpy, msgpack, gymnasium; no PyBullet,
# no torch) and an example random agent that plays against the server at $MULTION_SERVER.
#   docker build -f docker/agent.Dockerfile -t multion-agent .       (from the repository root)
#   docker run --rm -e MULTION_SERVER=http://host.docker.internal:8000 multion-agent

FROM python:3.11-slim
WORKDIR /app
COPY client ./client
RUN pip install --no-cache-dir ./client && rm -rf ./client
COPY docker/random_agent.py ./random_agent.py
RUN useradd --create-home multion
USER multion
ENV MULTION_SERVER=http://server:8000 \
    MULTION_TASK=3 \
    MULTION_EPISODES=3
CMD ["python", "random_agent.py"]
