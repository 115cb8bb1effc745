/* The worker pool: a parallel-for over job indices. The calling thread
   works too. Jobs write disjoint outputs, so the order in which threads pick
   them never shows in the result. */
#include "internal.h"

#ifndef RAST_NO_THREADS
#include <pthread.h>

typedef struct rast__pool {
    const rast_allocator *alloc;
    int workers;
    pthread_t threads[RAST_MAX_THREADS];
    pthread_mutex_t lock;
    pthread_cond_t wake, done;
    unsigned generation;
    int quit;
    int busy;               /* workers still inside the current generation */
    rast_job_fn fn;
    void *arg;
    int count;
    int next;               /* next job index to hand out */
} rast__pool;

/* The next job index, or -1 when all are handed out. An atomic add where
   the compiler has one (no lock traffic between jobs), else the mutex. */
static int rast__pool_take(rast__pool *p) {
    int i;
#if defined(__GNUC__) || defined(__clang__)
    i = __atomic_fetch_add(&p->next, 1, __ATOMIC_RELAXED);
    return i < p->count ? i : -1;
#else
    pthread_mutex_lock(&p->lock);
    i = p->next < p->count ? p->next++ : -1;
    pthread_mutex_unlock(&p->lock);
    return i;
#endif
}

static void *rast__pool_main(void *arg) {
    rast__pool *p = (rast__pool *)arg;
    unsigned seen = 0;
    for (;;) {
        int i;
        pthread_mutex_lock(&p->lock);
        while (!p->quit && p->generation == seen) pthread_cond_wait(&p->wake, &p->lock);
        if (p->quit) { pthread_mutex_unlock(&p->lock); return NULL; }
        seen = p->generation;
        pthread_mutex_unlock(&p->lock);
        while ((i = rast__pool_take(p)) >= 0) p->fn(p->arg, i);
        pthread_mutex_lock(&p->lock);
        if (--p->busy == 0) pthread_cond_signal(&p->done);
        pthread_mutex_unlock(&p->lock);
    }
}

static void rast__pool_destroy(rast__pool *p) {
    int i;
    if (!p) return;
    pthread_mutex_lock(&p->lock);
    p->quit = 1;
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->lock);
    for (i = 0; i < p->workers; ++i) pthread_join(p->threads[i], NULL);
    pthread_cond_destroy(&p->wake);
    pthread_cond_destroy(&p->done);
    pthread_mutex_destroy(&p->lock);
    rast__free(p->alloc, p);
}

/* Starts `workers` threads; NULL on failure (nothing left running), with
   *out_of_memory set when the allocation was what failed. */
static rast__pool *rast__pool_create(const rast_allocator *alloc, int workers, int *out_of_memory) {
    rast__pool *p = (rast__pool *)rast__calloc(alloc, 1, sizeof(rast__pool));
    int i;
    *out_of_memory = p == NULL;
    if (!p) return NULL;
    p->alloc = alloc;
    if (pthread_mutex_init(&p->lock, NULL) != 0) { rast__free(alloc, p); return NULL; }
    if (pthread_cond_init(&p->wake, NULL) != 0) {
        pthread_mutex_destroy(&p->lock);
        rast__free(alloc, p);
        return NULL;
    }
    if (pthread_cond_init(&p->done, NULL) != 0) {
        pthread_cond_destroy(&p->wake);
        pthread_mutex_destroy(&p->lock);
        rast__free(alloc, p);
        return NULL;
    }
    for (i = 0; i < workers; ++i) {
        if (pthread_create(&p->threads[i], NULL, rast__pool_main, p) != 0) {
            rast__pool_destroy(p);
            return NULL;
        }
        p->workers = i + 1;
    }
    return p;
}

static void rast__pool_run(rast__pool *p, int count, rast_job_fn fn, void *arg) {
    int i;
    pthread_mutex_lock(&p->lock);
    p->fn = fn;
    p->arg = arg;
    p->count = count;
    p->next = 0;
    p->busy = p->workers;
    p->generation++;
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->lock);
    while ((i = rast__pool_take(p)) >= 0) fn(arg, i);
    pthread_mutex_lock(&p->lock);
    while (p->busy > 0) pthread_cond_wait(&p->done, &p->lock);
    pthread_mutex_unlock(&p->lock);
}
#else
typedef struct rast__pool rast__pool;
static void rast__pool_destroy(rast__pool *p) { (void)p; }
#endif
